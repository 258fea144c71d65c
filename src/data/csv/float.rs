//! Number parsing for the readers: the language's own grammar and values (`str::parse::<f64>`),
//! faster on the plain decimal fields that make up a log.

/// Parses a whole (already trimmed) field as [`str::parse::<f64>`] does: the same accepted
/// texts and the same value, bit for bit.
///
/// `fast_float2` takes the field first; like the standard library it rounds correctly, and
/// its decimal grammar (`[+-]digits[.digits][(e|E)[+-]digits]`, at least one mantissa
/// digit, nothing after) is the standard library's, so a finite value from it is the
/// standard library's value. Anything else (`nan`, `inf`, `infinity`, an overflow to ±Inf,
/// junk, invalid UTF-8) takes the standard parser. The tests below and a property test in
/// `tests/it/csv_reader.rs` compare the two on random texts.
pub(crate) fn parse_f64(field: &[u8]) -> Option<f64> {
    match fast_float2::parse::<f64, _>(field) {
        Ok(x) if x.is_finite() => Some(x),
        _ => std::str::from_utf8(field).ok()?.parse::<f64>().ok(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agrees_with_the_standard_parser() {
        let cases = [
            "0",
            "-0",
            "+1",
            "1.",
            ".5",
            "-.5e-3",
            "1e",
            "1e+",
            "e5",
            ".",
            "+",
            "-",
            "",
            "1.2.3",
            "1e5",
            "1E-5",
            "nan",
            "NaN",
            "-inf",
            "+Infinity",
            "inf0",
            "0x10",
            "1_000",
            "1e999",
            "-1e-999",
            "2.2250738585072011e-308",
            "4.9e-324",
            "1.7976931348623157e308",
            "179769313486231580793728971405303415079934132710037826936173778980444968292764750946649017977587207096330286416692887910946555547851940402630657488671505820681908902000708383676273854845817711531764475730270069855571366959622842914819860834936475292719074168444365510704342711559699508093042880177904174497791.9999999",
            "0.30000000000000004",
            "123456789012345678901234567890",
            " 1",
            "1 ",
            "١",
        ];
        for c in cases {
            let std = c.parse::<f64>().ok().map(f64::to_bits);
            assert_eq!(parse_f64(c.as_bytes()).map(f64::to_bits), std, "{c:?}");
        }
        assert_eq!(parse_f64(b"\xff1"), None);
    }
}
