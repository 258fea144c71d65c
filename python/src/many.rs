//! `greybox.fit_many` and the Dask fleet: each log fitted on its own as `greybox fit --each`
//! does, one summary record per log (a log that fails is a record, never an exception), and
//! the records turned into the columns of `--summary`.

use crate::errors::{refused, to_py};
use crate::request::fit_request;
use crate::words::in_python_words;
use greybox::app::summary::columns;
use greybox::app::{Cell, Record, batch_plan, expand, fit_each, stem};
use pyo3::IntoPyObjectExt;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// The logs of a folder or a glob, as `greybox fit --each PATTERN` finds them (sorted by file
/// name).
///
/// Errors: `OptionError` when nothing matches or the glob is malformed.
#[pyfunction]
pub fn expand_logs(pattern: &str) -> PyResult<Vec<String>> {
    let paths = expand(pattern).map_err(to_py)?;
    Ok(paths.iter().map(|p| p.display().to_string()).collect())
}

/// The names `greybox fit --each` gives the logs `paths` in its summary: the shortest path
/// suffix that tells each from the others.
#[pyfunction]
pub fn log_names(paths: Vec<String>) -> Vec<String> {
    let paths: Vec<PathBuf> = paths.into_iter().map(PathBuf::from).collect();
    let stems: Vec<String> = paths.iter().map(|p| stem(p)).collect();
    greybox::app::unique_names(&paths, &stems)
}

/// Fits each of `paths` on its own (named `names`) with the keyword `options` on `threads` threads
/// (default: rayon's pool, `RAYON_NUM_THREADS` or the cores, as the batch), the GIL released; one summary record per log as JSON, in the order
/// of `paths`.
///
/// Errors: `OptionError` naming the keyword of an invalid option (before any log is read) or names that do not
/// match the paths; a log that cannot be read or fitted is a failed record.
#[pyfunction]
#[pyo3(signature = (paths, names, options, threads=None))]
pub fn fit_records(
    py: Python<'_>,
    paths: Vec<String>,
    names: Vec<String>,
    options: &Bound<'_, PyDict>,
    threads: Option<usize>,
) -> PyResult<Vec<String>> {
    if names.len() != paths.len() {
        return Err(refused("names", "one name per log"));
    }
    let a = fit_request(options)?;
    let mut plan = batch_plan(&a).map_err(|e| to_py(in_python_words(e)))?;
    if let Some((options, ..)) = plan.pem.as_mut() {
        options.pem.progress = false;
    }
    let paths: Vec<PathBuf> = paths.into_iter().map(PathBuf::from).collect();
    let threads = threads.unwrap_or_else(rayon::current_num_threads).max(1);
    let records = py.detach(|| fit_each(&a, &plan, &paths, &names, threads, in_python_words, |_, _| {}));
    records
        .iter()
        .map(|r| serde_json::to_string(r).map_err(|e| crate::errors::Error::new_err(e.to_string())))
        .collect()
}

/// One column of the summary: header, Arrow type name, one value per log.
type Column = (String, &'static str, Vec<Py<PyAny>>);

/// The columns of `--summary` for the records (JSON, as [`fit_records`] returns them):
/// `(header, arrow type name, values)` with `None` for an empty cell.
///
/// Errors: `Error` for a record that is not one of [`fit_records`]'s.
#[pyfunction]
pub fn summary_columns(py: Python<'_>, records: Vec<String>) -> PyResult<Vec<Column>> {
    let records: Vec<Record> = records
        .iter()
        .map(|r| {
            serde_json::from_str(r).map_err(|e| crate::errors::Error::new_err(format!("not a record: {e}")))
        })
        .collect::<PyResult<_>>()?;
    columns(&records)
        .into_iter()
        .map(|(name, cells)| {
            let kind = match name.as_str() {
                "log" | "name" | "status" | "error" | "hold" | "warnings" => "string",
                "pole_pairs" => "int64",
                "converged" => "bool",
                _ => "float64",
            };
            let values = cells
                .into_iter()
                .map(|c| match c {
                    Cell::Text(s) => s.into_py_any(py),
                    Cell::Count(n) => n.into_py_any(py),
                    Cell::Flag(b) => b.into_py_any(py),
                    Cell::Number(Some(v)) | Cell::Seconds(v) => v.into_py_any(py),
                    Cell::Number(None) | Cell::Missing => Ok(py.None()),
                })
                .collect::<PyResult<_>>()?;
            Ok((name, kind, values))
        })
        .collect()
}
