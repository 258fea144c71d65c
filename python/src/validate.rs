//! `greybox.validate`: Python keywords to the application layer's typed
//! [`ValidateRequest`] (each converted once, a wrong one refused naming the keyword), the
//! saved fit compared with each log by [`greybox::app::validate`] with the GIL released.

use crate::errors::{OptionError, to_py};
use crate::keyword::each;
use crate::reading::{Keywords, ReadingKeys};
use crate::words::in_python_words;
use greybox::app::{ValidateRequest, validate as compare, validation_json};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// The keywords of `validate` (its own in the order `greybox validate --help` lists them).
const VALIDATE: Keywords = Keywords {
    command: "validate",
    doc: "docs/cli.md",
    example: "pole_pairs=4",
    own: &["params", "pole_pairs", "hold"],
    reading: true,
    outputs: &["json", "compare_dir", "plot", "quiet"],
    returns: "validate() returns the report",
};

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
    each(options, |x| {
        match x.key {
            "params" => {
                r.params = PathBuf::from(x.text()?);
                params = true;
            }
            "pole_pairs" => r.pole_pairs = Some(x.count()?),
            "hold" => r.hold = Some(x.choice()?),
            other if reading.take(other, x)? => {}
            other => return Err(VALIDATE.not_taken(other)),
        }
        Ok(())
    })?;
    if !params {
        return Err(OptionError::new_err("params: required (a Fit, its report dict, or a report's path)"));
    }
    r.reading = reading.finish()?;
    let (saved, _, comparisons) = py.detach(|| compare(&logs, &r)).map_err(|e| to_py(in_python_words(e)))?;
    Ok(validation_json(&saved, &comparisons))
}
