//! Errors in the words of the command line: the library names its options by their field
//! names (`per_experiment`) and its models by their report names (`pmsm_spm`); the user
//! typed `--per-log` and `--model spm`.

use greybox::Error;

/// The flag of a library option name, or `None` when the name is not an option the command
/// line sets.
pub fn flag_of(option: &str) -> Option<&'static str> {
    Some(match option {
        "per_experiment" => "--per-log",
        "fixed" => "--fix",
        "bounds" => "--bounds",
        "start" => "--start",
        "huber" => "--huber",
        "hold" => "--hold",
        "voltage" => "--voltage",
        "voltage_limit" => "--u-dc",
        "weighting" => "--weighting",
        "prefilter" | "cutoff" => "--prefilter",
        "max_iters" => "--max-iters",
        "output_weights" => "--output-weights",
        "horizon" => "--horizon",
        "thermal" => "--t0/--r-s0/--psi-f0",
        "experiments" => "LOG",
        "model" | "salient" => "--model",
        "dead-time width" => "--dead-time-width",
        "dead-time mask" => "--dead-time-mask",
        "pole-pairs" => "--pole-pairs",
        "method" => "--method",
        "dead-time" => "--dead-time",
        "t0" => "--t0",
        "ftol" => "--ftol",
        "xtol" => "--xtol",
        "gtol" => "--gtol",
        "output" => "--json",
        _ => return None,
    })
}

/// Rewrites the library's model names in `text` as the `--model` values (`pmsm_spm` →
/// `spm`), and Rust's debug names of the motor kinds (`Spm`) likewise.
fn model_words(text: &str) -> String {
    text.replace("model `pmsm_spm`", "model spm (--model spm)")
        .replace("model `pmsm_ipm`", "model ipm (--model ipm)")
        .replace("the pmsm_spm model", "the spm model (--model spm)")
        .replace("the pmsm_ipm model", "the ipm model (--model ipm)")
        .replace("the Spm model", "the spm model (--model spm)")
        .replace("the Ipm model", "the ipm model (--model ipm)")
}

/// `e` with the option named by its flag and the model by its `--model` value; other
/// errors unchanged.
pub fn in_cli_words(e: Error) -> Error {
    match e {
        Error::InvalidOption { option, reason } => Error::InvalidOption {
            option: flag_of(&option).map_or(option, str::to_string),
            reason: model_words(&reason),
        },
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_become_flags() {
        let e = Error::InvalidOption {
            option: "per_experiment".into(),
            reason: "no parameter `x_s` in model `pmsm_spm`".into(),
        };
        let s = in_cli_words(e).to_string();
        assert_eq!(s, "invalid option `--per-log`: no parameter `x_s` in model spm (--model spm)");
        let e = Error::InvalidOption { option: "something else".into(), reason: "r".into() };
        assert!(in_cli_words(e).to_string().contains("`something else`"));
    }
}
