//! `greybox.fit`: one joint fit of logs (files or Arrow tables) with typed keyword options
//! (the application layer's [`greybox::app::FitRequest`]), the GIL released while the logs
//! are read and fitted.

use crate::errors::{refused, to_py};
use crate::request::fit_request;
use crate::words::in_python_words;
use greybox::Experiment;
use greybox::app::{FitOutcome, fit_experiments, plan, read_sources};
use greybox::pmsm::{LogSource, PmsmFit};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::time::Instant;

/// A finished fit as the Python `Fit` wraps it: the JSON report, the printed table, whether
/// the command line would exit 0 (trusted), and the fit with its logs for the plot.
#[pyclass(module = "greybox._greybox", frozen)]
pub struct NativeFit {
    json: String,
    text: String,
    markdown: String,
    trusted: bool,
    fit: Option<Box<PmsmFit>>,
    logs: Vec<Experiment>,
}

#[pymethods]
impl NativeFit {
    /// The JSON report, exactly what `greybox fit --json` writes (without the final newline).
    #[getter]
    fn json(&self) -> &str {
        &self.json
    }

    /// The report as the aligned text table `greybox fit` prints.
    #[getter]
    fn text(&self) -> &str {
        &self.text
    }

    /// The report as Markdown (`--format markdown`).
    #[getter]
    fn markdown(&self) -> &str {
        &self.markdown
    }

    /// Whether `greybox fit` would exit 0: converged, no untrusted warning (or
    /// `allow_unconverged`); 3 otherwise.
    #[getter]
    fn trusted(&self) -> bool {
        self.trusted
    }

    /// The fit plot (SVG text, what `--plot` writes); `None` for `method="ls"`, which
    /// draws none.
    fn svg(&self, py: Python<'_>) -> PyResult<Option<String>> {
        let Some(fit) = &self.fit else { return Ok(None) };
        // The steady-state equations simulate no currents: no plot, as for `method="ls"`.
        if fit.report.model.ends_with("_steady") {
            return Ok(None);
        }
        py.detach(|| greybox::app::plots::fit_svg(fit, &self.logs)).map(Some).map_err(to_py)
    }
}

/// A log as handed over: a file, or an Arrow table (its batches and schema) named `name`.
pub(crate) enum Source {
    Path(PathBuf),
    Table { name: String, schema: arrow_schema::SchemaRef, batches: Vec<arrow_array::RecordBatch> },
}

impl Source {
    /// A `str` is a path; anything else must offer the Arrow C stream (`__arrow_c_stream__`).
    pub(crate) fn extract(obj: &Bound<'_, PyAny>, name: String) -> PyResult<Self> {
        use arrow_pyarrow::FromPyArrow;
        if let Ok(path) = obj.extract::<String>() {
            return Ok(Self::Path(PathBuf::from(path)));
        }
        let table = arrow_pyarrow::Table::from_pyarrow_bound(obj).map_err(|e| {
            crate::errors::DataError::new_err(format!(
                "{name}: not a path and not an Arrow table (no usable __arrow_c_stream__): {e}"
            ))
        })?;
        let (batches, schema) = table.into_inner();
        Ok(Self::Table { name, schema, batches })
    }

    /// Each of `sources` (a path, or a table named by the name in its place in `names`).
    ///
    /// Errors: `OptionError` for a count of `names` other than of `sources`; `DataError`
    /// for an object that is neither a path nor an Arrow table ([`Source::extract`]).
    pub(crate) fn all(sources: &[Bound<'_, PyAny>], names: Vec<String>) -> PyResult<Vec<Self>> {
        if names.len() != sources.len() {
            return Err(refused("names", "one name per log"));
        }
        sources.iter().zip(names).map(|(obj, name)| Self::extract(obj, name)).collect()
    }

    /// The library's source of the log (borrowed).
    pub(crate) fn log_source(&self) -> LogSource<'_> {
        match self {
            Self::Path(p) => LogSource::Path(p),
            Self::Table { name, schema, batches } => LogSource::Arrow { name, schema, batches },
        }
    }
}

/// Fits `sources` (paths, or Arrow tables named by the `names` in their places) jointly with
/// the keyword `options` (the flags of `greybox fit` as keywords: `voltage="reference"`),
/// as `greybox fit SOURCES… FLAGS…` does; the GIL is released while the logs are read and
/// fitted.
///
/// Errors: `OptionError` naming the keyword for an invalid option, `DataError` for a log
/// that cannot be read (a missing column with the keywords that name the header's
/// look-alikes), `FitError` when the fit fails.
#[pyfunction]
pub fn fit(
    py: Python<'_>,
    sources: Vec<Bound<'_, PyAny>>,
    names: Vec<String>,
    options: &Bound<'_, PyDict>,
) -> PyResult<NativeFit> {
    let t0 = Instant::now();
    let a = fit_request(options)?;
    let mut plan = plan(&a).map_err(|e| to_py(in_python_words(e)))?;
    if let Some((options, ..)) = plan.pem.as_mut() {
        options.pem.progress = false;
    }
    let sources = Source::all(&sources, names)?;
    let (fitted, logs) = py
        .detach(|| {
            let sources: Vec<LogSource<'_>> = sources.iter().map(Source::log_source).collect();
            let logs = read_sources(&a.reading, &plan.csv, &sources)?;
            let read_s = t0.elapsed().as_secs_f64();
            fit_experiments(&a, &plan, &logs, t0, read_s).map(|f| (f, logs))
        })
        .map_err(|e| to_py(in_python_words(e)))?;
    let trusted = fitted.report().trusted() || a.allow_unconverged;
    let (fit, logs) = match fitted.outcome {
        FitOutcome::Pem(fit) => (Some(fit), logs),
        FitOutcome::Ls(_) => (None, Vec::new()),
    };
    Ok(NativeFit {
        text: fitted.document.to_text(),
        markdown: fitted.document.to_markdown(),
        json: fitted.json,
        trusted,
        fit,
        logs,
    })
}
