//! The names of a fit's options as the front ends spell them: the library names an option
//! by its field (`per_experiment`) or a phrase (`dead-time mask`); the request, the command
//! line and Python by the option's name (`per_log`: `--per-log`, `per_log=`); a message in
//! the command line's words rewritten in the keywords' ([`keywords`]).

/// The name of the fit's option that sets the library option `option` (its field name or
/// its phrase in [`crate::Error::InvalidOption`]), snake case (`per_log`; `t0/r_s0/psi_f0`
/// for the thermal reference's three; `LOG` for the logs themselves), or `None` when no
/// option of a fit sets it.
pub fn option_of(option: &str) -> Option<&'static str> {
    Some(match option {
        "per_experiment" => "per_log",
        "fixed" => "fix",
        "bounds" => "bounds",
        "start" => "start",
        "huber" => "huber",
        "hold" => "hold",
        "voltage" => "voltage",
        "voltage_limit" => "u_dc",
        "weighting" => "weighting",
        "prefilter" | "cutoff" => "prefilter",
        "max_iters" => "max_iters",
        "output_weights" => "output_weights",
        "horizon" => "horizon",
        "thermal" => "t0/r_s0/psi_f0",
        "experiments" => "LOG",
        "model" | "salient" => "model",
        "dead-time width" => "dead_time_width",
        "dead-time mask" => "dead_time_mask",
        "pole-pairs" => "pole_pairs",
        "method" => "method",
        "dead-time" => "dead_time",
        "t0" => "t0",
        "ftol" => "ftol",
        "xtol" => "xtol",
        "gtol" => "gtol",
        "output" => "json",
        "precision" => "precision",
        _ => return None,
    })
}

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
    "mras",
    "ekf",
    "normalised",
    "lyapunov",
    "relay",
];

/// `text` (a message in the command line's words) with every `--flag` written as the
/// Python keyword (`flag`, hyphens as underscores), and `--flag VALUE`, for the values
/// messages use (`estimate`, `reference`, `ls`, …), as `flag="VALUE"`: `--dead-time
/// estimate` → `dead_time="estimate"`.
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
        assert_eq!(keywords("add --estimator mras, or drop it"), "add estimator=\"mras\", or drop it");
    }
}
