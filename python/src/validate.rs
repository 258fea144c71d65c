//! `greybox.validate`: Python keywords to the application layer's typed
//! [`ValidateRequest`] (each converted once, a wrong one refused naming the keyword), the
//! saved fit compared with each log by [`greybox::app::validate`] with the GIL released.

use crate::errors::{OptionError, refused, to_py};
use crate::keyword::Value;
use crate::reading::{READING_KEYWORDS, ReadingKeys, unknown};
use crate::words::in_python_words;
use greybox::app::{ValidateRequest, validate as compare, validation_json};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// The keywords of `validate` besides the reading's, in the order `greybox validate --help`
/// lists their flags.
const VALIDATE_KEYWORDS: &[&str] = &["params", "pole_pairs", "hold"];

/// Validates the saved fit of the keyword `params` (a report's path) on `logs` with the
/// keyword `options` (`pole_pairs`, `hold` and the reading's), as `greybox validate` does,
/// the GIL released; the JSON of `validate --json`.
///
/// Errors: `OptionError` naming the keyword, `DataError` (an unreadable log or report),
/// `FitError` (a simulation that fails).
#[pyfunction]
pub fn validate(py: Python<'_>, logs: Vec<PathBuf>, options: &Bound<'_, PyDict>) -> PyResult<String> {
    let mut r = ValidateRequest::new(PathBuf::new());
    let mut params = false;
    let mut reading = ReadingKeys::new(r.reading.csv.clone());
    for (k, v) in options.iter() {
        let key: String = k.extract()?;
        if v.is_none() {
            continue;
        }
        let x = Value { key: &key, v: &v };
        match key.as_str() {
            "params" => {
                r.params = PathBuf::from(x.text()?);
                params = true;
            }
            "pole_pairs" => r.pole_pairs = Some(x.count()?),
            "hold" => r.hold = Some(x.choice()?),
            other if reading.take(other, &x)? => {}
            "json" | "compare_dir" | "plot" | "quiet" => {
                return Err(refused(
                    &key,
                    "the Python functions write no files: validate() returns the report",
                ));
            }
            other => {
                let known: Vec<&str> = VALIDATE_KEYWORDS.iter().chain(READING_KEYWORDS).copied().collect();
                return Err(unknown(other, &known, "validate", "docs/cli.md", "pole_pairs=4"));
            }
        }
    }
    if !params {
        return Err(OptionError::new_err("params: required (a Fit, its report dict, or a report's path)"));
    }
    r.reading = reading.finish()?;
    let (saved, _, comparisons) = py.detach(|| compare(&logs, &r)).map_err(|e| to_py(in_python_words(e)))?;
    Ok(validation_json(&saved, &comparisons))
}
