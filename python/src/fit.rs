//! `greybox.fit`: one joint fit of logs (files or Arrow tables) with the command line's
//! options, the GIL released while the logs are read and fitted.

use crate::errors::{from_clap, refused, to_py};
use greybox::Experiment;
use greybox::cli::args::FitArgs;
use greybox::cli::errors::in_fit_words;
use greybox::cli::fitted::{FitOutcome, fit_experiments, read_sources};
use greybox::pmsm::{LogSource, PmsmFit};
use pyo3::prelude::*;
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
        py.detach(|| greybox::cli::plots::fit_svg(fit, &self.logs)).map(Some).map_err(to_py)
    }
}

/// A log as handed over: a file, or an Arrow table (its batches and schema) named `name`.
enum Source {
    Path(PathBuf),
    Table { name: String, schema: arrow_schema::SchemaRef, batches: Vec<arrow_array::RecordBatch> },
}

impl Source {
    /// A `str` is a path; anything else must offer the Arrow C stream (`__arrow_c_stream__`).
    fn extract(obj: &Bound<'_, PyAny>, name: String) -> PyResult<Self> {
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

    fn log_source(&self) -> LogSource<'_> {
        match self {
            Self::Path(p) => LogSource::Path(p),
            Self::Table { name, schema, batches } => LogSource::Arrow { name, schema, batches },
        }
    }
}

/// Parses `argv` (the flags of `greybox fit` after `fit`) with the command line's parser,
/// refusing the file outputs a Python call has no use for.
pub fn parse_fit(argv: &[String]) -> PyResult<FitArgs> {
    let a: FitArgs = greybox::cli::parse("fit", argv).map_err(from_clap)?;
    let outputs = [
        ("--json", a.json.is_some()),
        ("--plot", a.plot.is_some()),
        ("--residuals", a.residuals.is_some()),
        ("--each", a.each.is_some()),
        ("--summary", a.summary.is_some()),
        ("--trend", a.trend.is_some()),
    ];
    if let Some((flag, _)) = outputs.iter().find(|(_, given)| *given) {
        return Err(refused(
            flag,
            "the Python functions write no files: use Fit.to_json(), Fit.svg(), fit_many() for a summary",
        ));
    }
    Ok(a)
}

/// Fits `sources` (paths, or Arrow tables named by the `names` in their places) jointly with the flags `argv`, as
/// `greybox fit SOURCES… ARGV…` does; the GIL is released while the logs are read and fitted.
///
/// Errors: `OptionError` for invalid flags, `DataError` for a log that cannot be read,
/// `FitError` when the fit fails; messages as the command line's.
#[pyfunction]
pub fn fit(
    py: Python<'_>,
    sources: Vec<Bound<'_, PyAny>>,
    names: Vec<String>,
    argv: Vec<String>,
) -> PyResult<NativeFit> {
    let t0 = Instant::now();
    let a = parse_fit(&argv)?;
    let mut plan = greybox::cli::plan::plan(&a).map_err(|e| to_py(in_fit_words(e)))?;
    if let Some((options, ..)) = plan.pem.as_mut() {
        options.pem.progress = false;
    }
    if names.len() != sources.len() {
        return Err(refused("names", "one name per log"));
    }
    let sources: Vec<Source> =
        sources.iter().zip(names).map(|(obj, name)| Source::extract(obj, name)).collect::<PyResult<_>>()?;
    let (fitted, logs) = py
        .detach(|| {
            let sources: Vec<LogSource<'_>> = sources.iter().map(Source::log_source).collect();
            let logs = read_sources(&a, &plan, &sources)?;
            let read_s = t0.elapsed().as_secs_f64();
            fit_experiments(&a, &plan, &logs, t0, read_s).map(|f| (f, logs))
        })
        .map_err(|e| to_py(in_fit_words(e)))?;
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
