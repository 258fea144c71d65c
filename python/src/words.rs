//! The library's errors in the words of the Python keywords: an option named by its keyword
//! (`per_log`, not `per_experiment` or `--per-log`), the command line's flags in a message
//! as keywords (`--voltage reference` → `voltage="reference"`), and a missing column with
//! the keywords that name the header's look-alikes, all in one message.

use greybox::Error;
use greybox::app::Choice;
use greybox::app::columns::{renamed_columns, speed_unit_in_header};
use greybox::app::words::keywords;

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
