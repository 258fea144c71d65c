//! The library's errors in the words of the Python keywords: an option named by its keyword
//! (`per_log`, not `per_experiment` or `--per-log`), the command line's flags in a message
//! as keywords (`--voltage reference` → `voltage="reference"`), and a missing column with
//! the keywords that name the header's look-alikes, all in one message.

use greybox::Error;
use greybox::app::Choice;
use greybox::app::columns::{renamed_columns, speed_unit_in_header};

/// The values a flag in a message may be followed by, written as the keyword's string.
const VALUES: &[&str] = &[
    "estimate",
    "reference",
    "actual",
    "ls",
    "pem",
    "iv",
    "auto",
    "pwm",
    "none",
    "logged",
    "stator",
    "dq",
    "spm",
    "ipm",
    "spm-steady",
    "ipm-steady",
    "rpm",
    "sine",
    "single",
    "rising",
    "falling",
    "min-max",
];

/// `text` with every `--flag` written as its keyword (`flag`), and `--flag VALUE` with a
/// value of [`VALUES`] as `flag="VALUE"`.
pub fn keywords(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find("--") {
        let starts_word = rest[..i].chars().last().is_none_or(|c| !c.is_alphanumeric());
        out.push_str(&rest[..i]);
        let after = &rest[i + 2..];
        let len = after.find(|c: char| !(c.is_ascii_alphanumeric() || c == '-')).unwrap_or(after.len());
        if !starts_word || len == 0 {
            out.push_str("--");
            rest = after;
            continue;
        }
        let key = after[..len].replace('-', "_");
        let tail = &after[len..];
        let value = tail.strip_prefix(' ').and_then(|t| {
            let n = t.find(|c: char| !(c.is_ascii_alphanumeric() || c == '-')).unwrap_or(t.len());
            VALUES.contains(&&t[..n]).then_some(&t[..n])
        });
        match value {
            Some(v) => {
                out.push_str(&format!("{key}=\"{v}\""));
                rest = &tail[1 + v.len()..];
            }
            None => {
                out.push_str(&key);
                rest = tail;
            }
        }
    }
    out.push_str(rest);
    out
}

/// `e` in the words of the Python keywords (see the module doc); other errors unchanged.
pub fn in_python_words(e: Error) -> Error {
    match e {
        Error::InvalidOption { option, reason } => {
            let option = greybox::app::words::option_of(&option)
                .map(str::to_string)
                .unwrap_or_else(|| keywords(&option).trim_start_matches("--").replace('-', "_"));
            let reason = reason
                .replace("model `pmsm_spm`", "model spm (model=\"spm\")")
                .replace("model `pmsm_ipm`", "model ipm (model=\"ipm\")")
                .replace("the pmsm_spm model", "the spm model (model=\"spm\")")
                .replace("the pmsm_ipm model", "the ipm model (model=\"ipm\")");
            Error::InvalidOption { option, reason: keywords(&reason) }
        }
        Error::MissingColumn { path, column, available } => {
            let found = renamed_columns(&available);
            let Some((_, _, like)) = found.iter().find(|(s, _, _)| *s == column).or(found.first()) else {
                return Error::MissingColumn { path, column, available };
            };
            let unit = speed_unit_in_header(&available).and_then(|u| {
                let name = greybox::pmsm::SpeedUnit::NAMES.iter().find(|(_, x)| *x == u)?.0;
                Some(format!("speed_unit=\"{name}\""))
            });
            let each: Vec<String> =
                found.iter().map(|(_, k, h)| format!("{k}=\"{h}\"")).chain(unit.clone()).collect();
            let map: Vec<String> = found.iter().map(|(s, _, h)| format!("\"{s}\": \"{h}\"")).collect();
            let one: Vec<String> =
                std::iter::once(format!("columns={{{}}}", map.join(", "))).chain(unit).collect();
            Error::Format {
                path: path.clone(),
                message: format!(
                    "no column `{column}` in the header ({available}); `{like}` looks like it. The header's names \
                     as keywords: {}; or in one: {}",
                    each.join(", "),
                    one.join(", ")
                ),
            }
        }
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_become_keywords() {
        assert_eq!(
            keywords("add --dead-time estimate (or a known voltage)"),
            "add dead_time=\"estimate\" (or a known voltage)"
        );
        assert_eq!(
            keywords("--method ls cannot honour --start, --fix"),
            "method=\"ls\" cannot honour start, fix"
        );
        assert_eq!(keywords("--t0/--r-s0/--psi-f0"), "t0/r_s0/psi_f0");
        assert_eq!(
            keywords("replaces the averaged --dead-time model"),
            "replaces the averaged dead_time model"
        );
        assert_eq!(keywords("a-- b"), "a-- b");
    }
}
