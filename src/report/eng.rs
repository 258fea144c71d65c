//! Engineering notation for reports: an SI prefix chosen per quantity (mΩ, mH, mV s/rad,
//! µA), so that a table reads `4.5000 mH` instead of `4.5e-3 H`.
//!
//! The prefix puts the mantissa of the reference value (the estimate) in `[1, 1000)`; the
//! standard error and the interval of that estimate are printed with the same prefix, so
//! that the digits line up. Units without a sensible prefix (`N m/A`, `°C`, `samples`,
//! dimensionless) are printed in their base unit.

/// SI prefixes from pico to giga, as (exponent of ten, symbol).
const PREFIXES: [(i32, &str); 8] =
    [(-12, "p"), (-9, "n"), (-6, "µ"), (-3, "m"), (0, ""), (3, "k"), (6, "M"), (9, "G")];

/// The symbol shown for a unit as the library names it (`ohm` → `Ω`, `degC` → `°C`), and
/// whether an SI prefix may stand in front of it.
pub fn display_unit(unit: &str) -> (String, bool) {
    match unit {
        "ohm" | "Ω" => ("Ω".into(), true),
        "degC" | "°C" => ("°C".into(), false),
        "H" | "V" | "A" | "V s" | "V s/rad" | "s" | "W" | "N m" | "V²" | "A²" => (unit.into(), true),
        other => (other.into(), false),
    }
}

/// A display unit for one quantity: the prefixed symbol and the factor that converts a
/// value in the base unit into it (`value / factor`).
#[derive(Clone, Debug, PartialEq)]
pub struct UnitScale {
    /// Prefixed symbol, e.g. `mH`; empty for a dimensionless quantity.
    pub symbol: String,
    /// `10^exponent` of the prefix (1 without one).
    pub factor: f64,
}

impl UnitScale {
    /// The scale for a quantity of magnitude `reference` in `unit` (library spelling): the
    /// prefix that puts `|reference|` in `[1, 1000)` (clipped to pico–giga), or none for
    /// zero, a non-finite reference, or a unit that takes no prefix.
    pub fn for_value(reference: f64, unit: &str) -> Self {
        let (symbol, prefixable) = display_unit(unit);
        let exp = if prefixable { prefix_exponent(reference) } else { 0 };
        Self::with_exponent(exp, &symbol)
    }

    fn with_exponent(exp: i32, symbol: &str) -> Self {
        let p = PREFIXES.iter().find(|(e, _)| *e == exp).map_or("", |(_, p)| p);
        Self { symbol: format!("{p}{symbol}"), factor: 10f64.powi(exp) }
    }

    /// `value` in this unit with `decimals` digits after the point, without the symbol;
    /// `∞`/`−∞`/`NaN` spelled out.
    pub fn number(&self, value: f64, decimals: usize) -> String {
        if !value.is_finite() {
            return non_finite(value);
        }
        format!("{:.decimals$}", value / self.factor)
    }

    /// `value` in this unit with `decimals` digits and the symbol, e.g. `4.5000 mH`.
    pub fn with_unit(&self, value: f64, decimals: usize) -> String {
        join(self.number(value, decimals), &self.symbol)
    }
}

/// `number unit`, or the number alone for an empty unit.
fn join(number: String, symbol: &str) -> String {
    if symbol.is_empty() { number } else { format!("{number} {symbol}") }
}

fn non_finite(v: f64) -> String {
    if v.is_nan() {
        "NaN".into()
    } else if v > 0.0 {
        "∞".into()
    } else {
        "−∞".into()
    }
}

/// The exponent (multiple of 3, −12 to 9) that puts `|v|` in `[1, 1000)`; 0 for zero or a
/// non-finite value. Rounding to 5 significant digits is taken into account, so that
/// `0.99999996` gives `1.0000` and not `1000.00 m`.
pub fn prefix_exponent(v: f64) -> i32 {
    if v == 0.0 || !v.is_finite() {
        return 0;
    }
    let rounded = round_significant(v.abs(), 5);
    let e = rounded.log10().floor() as i32;
    (e.div_euclid(3) * 3).clamp(-12, 9)
}

/// `v` rounded to `digits` significant digits.
fn round_significant(v: f64, digits: i32) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let e = v.abs().log10().floor() as i32;
    let f = 10f64.powi(digits - 1 - e);
    (v * f).round() / f
}

/// Digits after the point that show `scaled` (a value already in the display unit) with
/// `significant` significant digits; 0 for zero or non-finite values, at most 12.
pub fn decimals_for(scaled: f64, significant: usize) -> usize {
    if scaled == 0.0 || !scaled.is_finite() {
        return significant.saturating_sub(1).min(12);
    }
    let e = round_significant(scaled.abs(), significant as i32).log10().floor() as i32;
    (significant as i32 - 1 - e).clamp(0, 12) as usize
}

/// `value` in engineering notation with `significant` significant digits and its unit, the
/// prefix chosen from the value itself: `format_eng(0.0045, "H", 5)` = `"4.5000 mH"`,
/// `format_eng(0.9, "ohm", 4)` = `"900.0 mΩ"`.
pub fn format_eng(value: f64, unit: &str, significant: usize) -> String {
    let s = UnitScale::for_value(value, unit);
    let d = decimals_for(value / s.factor, significant);
    s.with_unit(value, d)
}

/// A figure with its unit for the running text of a report (loss, mse, residuals): the
/// engineering form when the unit takes a prefix, else four significant digits in
/// scientific form for values far from 1 (`1.795e-6 A²` is not written for squared units,
/// which take no prefix in this crate: `µA²` would be ambiguous).
pub fn format_figure(value: f64, unit: &str) -> String {
    let (symbol, prefixable) = display_unit(unit);
    let squared = symbol.ends_with('²');
    if prefixable && !squared {
        return format_eng(value, unit, 4);
    }
    if !value.is_finite() {
        return join(non_finite(value), &symbol);
    }
    let a = value.abs();
    let n =
        if a != 0.0 && !(1e-3..1e4).contains(&a) { format!("{value:.3e}") } else { format!("{value:.4}") };
    join(n, &symbol)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefixes_are_chosen_per_value() {
        assert_eq!(format_eng(0.0045, "H", 5), "4.5000 mH");
        assert_eq!(format_eng(0.9, "ohm", 5), "900.00 mΩ");
        assert_eq!(format_eng(0.538_887_72, "V s/rad", 5), "538.89 mV s/rad");
        assert_eq!(format_eng(1.19e-3, "A", 3), "1.19 mA");
        assert_eq!(format_eng(2.17e-10, "H", 3), "217 pH");
        assert_eq!(format_eng(2.4816, "A", 5), "2.4816 A");
        assert_eq!(format_eng(1500.0, "V", 4), "1.500 kV");
        assert_eq!(format_eng(-0.02, "A", 2), "-20 mA");
    }

    #[test]
    fn rounding_moves_to_the_next_prefix() {
        assert_eq!(format_eng(0.999_999_96, "ohm", 5), "1.0000 Ω");
        assert_eq!(format_eng(999.999_6e-6, "H", 5), "1.0000 mH");
    }

    #[test]
    fn units_without_prefix_and_odd_values() {
        assert_eq!(format_eng(0.66, "N m/A", 4), "0.6600 N m/A");
        assert_eq!(format_eng(85.3, "degC", 3), "85.3 °C");
        assert_eq!(format_eng(1.0, "samples", 2), "1.0 samples");
        assert_eq!(format_eng(0.0, "H", 3), "0.00 H");
        assert_eq!(format_eng(f64::INFINITY, "ohm", 3), "∞ Ω");
        assert_eq!(format_eng(f64::NAN, "H", 3), "NaN H");
        // Beyond pico and giga the mantissa leaves [1, 1000) rather than inventing prefixes.
        assert_eq!(format_eng(1e-15, "H", 2), "0.0010 pH");
    }

    #[test]
    fn figures_with_squared_units_stay_scientific() {
        assert_eq!(format_figure(1.794_936e-6, "A²"), "1.795e-6 A²");
        assert_eq!(format_figure(0.5, "A²"), "0.5000 A²");
        assert_eq!(format_figure(7.98e-6, "A"), "7.980 µA");
        assert_eq!(format_figure(-925_351.2, ""), "-9.254e5");
    }

    #[test]
    fn one_scale_for_a_value_and_its_interval() {
        let s = UnitScale::for_value(4.5e-3, "H");
        assert_eq!(s.symbol, "mH");
        assert_eq!(s.number(4.4999e-3, 4), "4.4999");
        assert_eq!(s.with_unit(2.0e-6, 4), "0.0020 mH");
    }
}
