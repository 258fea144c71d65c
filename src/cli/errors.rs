//! Errors in the words of the command line: the library names its options by their field
//! names (`per_experiment`) and its models by their report names (`pmsm_spm`); the user
//! typed `--per-log` and `--model spm`.

use crate::Error;

/// The flag of a library option name, or `None` when the name is not an option the command
/// line sets: `--` and the option's name ([`crate::app::words::option_of`]) in kebab case,
/// `LOG` for the logs.
pub fn flag_of(option: &str) -> Option<String> {
    let name = crate::app::words::option_of(option)?;
    if name == "LOG" {
        return Some(name.into());
    }
    Some(name.split('/').map(|n| format!("--{}", n.replace('_', "-"))).collect::<Vec<_>>().join("/"))
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
/// errors unchanged. The flag is looked up in [`flag_of`] for `greybox fit`, then among
/// the long flags of `command` (the subcommand that ran): an option `gamma_ke` or
/// `gamma-ke` becomes `--gamma-ke` when the command has that flag. An option that is
/// not a flag (a scenario-file path such as `motor.r_s`) is left as it is.
pub fn in_cli_words(e: Error, command: &clap::Command) -> Error {
    match e {
        Error::InvalidOption { option, reason } => {
            let fit = command.get_name() == "fit";
            let kebab = option.replace('_', "-");
            let flag = fit.then(|| flag_of(&option)).flatten().or_else(|| {
                command
                    .get_arguments()
                    .find(|a| {
                        a.get_long() == Some(&kebab)
                            || a.get_all_aliases().is_some_and(|v| v.contains(&kebab.as_str()))
                    })
                    .and_then(|a| a.get_long())
                    .map(|l| format!("--{l}"))
            });
            Error::InvalidOption { option: flag.unwrap_or(option), reason: model_words(&reason) }
        }
        Error::MissingColumn { path, column, available } => match column_hint(&column, &available, command) {
            Some((flag, found)) => {
                // Every standard column the header names otherwise, in one run (a log
                // with `Id, Iq, Ud, Uq, speed_rpm` took one run per column).
                let hints: Vec<(String, String, &str)> = command
                    .get_arguments()
                    .filter_map(|a| {
                        let long = a.get_long()?;
                        let default = a.get_default_values().first()?.to_str()?;
                        let absent = !available.split(", ").any(|h| h == default);
                        let (f, h) = (long.starts_with("col-") && absent)
                            .then(|| column_hint(default, &available, command))
                            .flatten()?;
                        Some((f, h, default))
                    })
                    .collect();
                let unit = speed_unit_hint(&available, command);
                let all: Vec<String> =
                    hints.iter().map(|(f, h, _)| format!("{f} \"{h}\"")).chain(unit.clone()).collect();
                // The same in `--columns`' one flag, where the command has it.
                let one = command.get_arguments().any(|a| a.get_long() == Some("columns")).then(|| {
                    let pairs: Vec<String> = hints.iter().map(|(_, h, d)| format!("{d}={h}")).collect();
                    let one = format!("--columns \"{}\"", pairs.join(","));
                    format!(
                        "; or in one flag: {}",
                        [Some(one), unit].into_iter().flatten().collect::<Vec<_>>().join(" ")
                    )
                });
                Error::InvalidOption {
                    option: flag.clone(),
                    reason: format!(
                        "{}: no column `{column}` in the header ({available}); `{found}` looks like it. The header's names \
                         as flags: {}{}",
                        path.display(),
                        all.join(" "),
                        one.unwrap_or_default()
                    ),
                }
            }
            None => Error::MissingColumn { path, column, available },
        },
        other => other,
    }
}

/// `--speed-unit U` when the header's speed column says its unit in its name (`speed_rpm`)
/// and the command takes the flag.
fn speed_unit_hint(available: &str, command: &clap::Command) -> Option<String> {
    use crate::app::Choice;
    command.get_arguments().find(|a| a.get_long() == Some("speed-unit"))?;
    let unit = crate::app::columns::speed_unit_in_header(available)?;
    let name = crate::pmsm::SpeedUnit::NAMES.iter().find(|(_, u)| *u == unit)?.0;
    Some(format!("--speed-unit {name}"))
}

/// For a missing standard column: the flag that names it (the command's `--col-*` whose
/// default is the column) and the header entry that looks like it.
fn column_hint(column: &str, available: &str, command: &clap::Command) -> Option<(String, String)> {
    let found = crate::app::columns::look_alike(column, available)?;
    let flag = command.get_arguments().find(|a| {
        a.get_long().is_some_and(|l| l.starts_with("col-")) && a.get_default_values() == [column]
    })?;
    Some((format!("--{}", flag.get_long()?), found.to_string()))
}

/// [`in_cli_words`] for `greybox fit`'s flags, where the subcommand is not at hand (a
/// batch's per-log errors).
pub fn in_fit_words(e: Error) -> Error {
    let fit = <super::args::FitArgs as clap::Args>::augment_args(clap::Command::new("fit"));
    in_cli_words(e, &fit)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn command(name: &'static str) -> clap::Command {
        clap::Command::new(name)
            .arg(clap::Arg::new("gamma_ke").long("gamma-ke"))
            .arg(clap::Arg::new("l_s").long("l-s").visible_alias("l-d"))
            .arg(clap::Arg::new("json").long("json"))
    }

    #[test]
    fn options_become_flags() {
        let e = Error::InvalidOption {
            option: "per_experiment".into(),
            reason: "no parameter `x_s` in model `pmsm_spm`".into(),
        };
        let s = in_cli_words(e, &command("fit")).to_string();
        assert_eq!(s, "invalid option `--per-log`: no parameter `x_s` in model spm (--model spm)");
        let e = Error::InvalidOption { option: "something else".into(), reason: "r".into() };
        assert!(in_cli_words(e, &command("fit")).to_string().contains("`something else`"));
    }

    #[test]
    fn options_of_other_commands_become_their_flags() {
        let flag = |option: &str| match in_cli_words(
            Error::InvalidOption { option: option.into(), reason: "r".into() },
            &command("track"),
        ) {
            Error::InvalidOption { option, .. } => option,
            other => panic!("{other}"),
        };
        assert_eq!(flag("gamma_ke"), "--gamma-ke");
        assert_eq!(flag("gamma-ke"), "--gamma-ke");
        assert_eq!(flag("l-d"), "--l-s");
        // `fit`'s table is not used for other commands: `output` is not `--json` here.
        assert_eq!(flag("output"), "output");
        assert_eq!(flag("motor.r_s"), "motor.r_s");
    }
}
