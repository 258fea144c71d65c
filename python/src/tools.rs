//! `greybox.simulate` and the fits of issue 33
//! (`fluxmap`, `saturation`, `standstill`, `mechanics`): the command line's subcommands
//! with their results handed back instead of printed or written.

use crate::errors::{from_clap, refused, to_py};
use arrow_pyarrow::ToPyArrow;
use greybox::cli::errors::in_cli_words;
use greybox::cli::fluxmap::FluxMapArgs;
use greybox::cli::mechanics::MechanicsArgs;
use greybox::cli::output::Outcome;
use greybox::cli::saturation::SaturationArgs;
use greybox::cli::simulate::SimulateArgs;
use greybox::cli::standstill::StandstillArgs;
use greybox::cli::{command, parse};
use pyo3::prelude::*;

/// `e` in the words of the subcommand `name` with the flags of `T`, as a Python exception.
fn words<T: clap::Args>(name: &'static str) -> impl Fn(greybox::Error) -> PyErr {
    move |e| to_py(in_cli_words(e, &command::<T>(name)))
}

/// Simulates the closed-loop drive of `greybox simulate` (the flags `argv`), the GIL
/// released: the log as a pyarrow RecordBatch (time column `t` [s], then the channels, as
/// the written Parquet/Arrow log) and the truth as JSON (the `.truth.json` file's).
///
/// Errors: `OptionError` for an unknown scenario or field or a bad value, `FitError` for a
/// diverging simulation.
#[pyfunction]
pub fn simulate(py: Python<'_>, argv: Vec<String>) -> PyResult<(Py<PyAny>, String)> {
    // `--print-config` only lifts the parser's need of `-o`: the scenario is built the same.
    let mut argv = argv;
    argv.push("--print-config".into());
    let a: SimulateArgs = parse("simulate", &argv).map_err(from_clap)?;
    if a.output.is_some() {
        return Err(refused("--output", "the Python functions write no files: simulate() returns the log"));
    }
    let cfg = greybox::cli::simulate::config(&a).map_err(words::<SimulateArgs>("simulate"))?;
    let log =
        py.detach(|| greybox::drive::simulate_drive(&cfg)).map_err(words::<SimulateArgs>("simulate"))?;
    let batch = greybox::data::to_record_batch(&log.experiment, "t").map_err(to_py)?;
    let truth =
        serde_json::to_string_pretty(&log.truth).map_err(|e| crate::errors::Error::new_err(e.to_string()))?;
    Ok((batch.to_pyarrow(py)?.unbind(), truth))
}

/// Runs the fitting subcommand `command` (`fluxmap`, `saturation`, `standstill` or
/// `mechanics`) with the flags `argv`, the GIL released: its JSON report (as `--json`
/// writes it) and the codes of the reasons it is not to be trusted (empty: trusted; the
/// command line's exit code 3 otherwise).
///
/// Errors: `OptionError` for an unknown command, a bad flag or `--json` (no files are
/// written), `DataError`, `FitError` with the command line's messages.
#[pyfunction]
pub fn report(py: Python<'_>, command: &str, argv: Vec<String>) -> PyResult<(String, Vec<String>)> {
    fn run<T: clap::Args + clap::FromArgMatches + Send + Sync>(
        py: Python<'_>,
        name: &'static str,
        argv: &[String],
        json: impl Fn(&T) -> bool,
        outcome: impl Fn(&T) -> greybox::Result<Outcome> + Send + Sync,
    ) -> PyResult<(String, Vec<String>)> {
        let a: T = parse(name, argv).map_err(from_clap)?;
        if json(&a) {
            return Err(refused("--json", "the Python functions write no files: the report is returned"));
        }
        let o = py.detach(|| outcome(&a)).map_err(words::<T>(name))?;
        Ok((o.json, o.untrusted))
    }
    match command {
        "fluxmap" => run::<FluxMapArgs>(
            py,
            "fluxmap",
            &argv,
            |a| a.report.json.is_some(),
            greybox::cli::fluxmap::fluxmap_outcome,
        ),
        "saturation" => run::<SaturationArgs>(
            py,
            "saturation",
            &argv,
            |a| a.report.json.is_some(),
            greybox::cli::saturation::saturation_outcome,
        ),
        "standstill" => run::<StandstillArgs>(
            py,
            "standstill",
            &argv,
            |a| a.report.json.is_some(),
            greybox::cli::standstill::standstill_outcome,
        ),
        "mechanics" => run::<MechanicsArgs>(
            py,
            "mechanics",
            &argv,
            |a| a.report.json.is_some(),
            greybox::cli::mechanics::mechanics_outcome,
        ),
        other => {
            Err(refused("command", &format!("`{other}`: one of fluxmap, saturation, standstill, mechanics")))
        }
    }
}
