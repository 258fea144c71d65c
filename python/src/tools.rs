//! The fits of issue 33
//! (`fluxmap`, `saturation`, `standstill`, `mechanics`): the command line's subcommands
//! with their results handed back instead of printed or written.

use crate::errors::{from_clap, refused, to_py};
use greybox::cli::errors::in_cli_words;
use greybox::cli::fluxmap::FluxMapArgs;
use greybox::cli::mechanics::MechanicsArgs;
use greybox::cli::output::Outcome;
use greybox::cli::saturation::SaturationArgs;
use greybox::cli::standstill::StandstillArgs;
use greybox::cli::{command, parse};
use pyo3::prelude::*;

/// `e` in the words of the subcommand `name` with the flags of `T`, as a Python exception.
fn words<T: clap::Args>(name: &'static str) -> impl Fn(greybox::Error) -> PyErr {
    move |e| to_py(in_cli_words(e, &command::<T>(name)))
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
