//! `greybox.validate`, `greybox.track`, `greybox.simulate` and the fits of issue 33
//! (`fluxmap`, `saturation`, `standstill`, `mechanics`): the command line's subcommands
//! with their results handed back instead of printed or written.

use crate::errors::{from_clap, refused, to_py};
use arrow_array::{ArrayRef, Float64Array, RecordBatch};
use arrow_pyarrow::ToPyArrow;
use greybox::cli::errors::in_cli_words;
use greybox::cli::fluxmap::FluxMapArgs;
use greybox::cli::mechanics::MechanicsArgs;
use greybox::cli::output::Outcome;
use greybox::cli::saturation::SaturationArgs;
use greybox::cli::simulate::SimulateArgs;
use greybox::cli::standstill::StandstillArgs;
use greybox::cli::track::TrackArgs;
use greybox::cli::validate::ValidateArgs;
use greybox::cli::{command, parse};
use pyo3::prelude::*;
use std::sync::Arc;

/// `e` in the words of the subcommand `name` with the flags of `T`, as a Python exception.
fn words<T: clap::Args>(name: &'static str) -> impl Fn(greybox::Error) -> PyErr {
    move |e| to_py(in_cli_words(e, &command::<T>(name)))
}

/// Validates the saved fit of `--params` on the logs of `argv` (the flags of `greybox
/// validate`), the GIL released; the JSON of `validate --json`.
///
/// Errors: `OptionError`, `DataError`, `FitError` with the command line's messages.
#[pyfunction]
pub fn validate(py: Python<'_>, argv: Vec<String>) -> PyResult<String> {
    let a: ValidateArgs = parse("validate", &argv).map_err(from_clap)?;
    for (flag, given) in [
        ("--json", a.json.is_some()),
        ("--plot", a.plot.is_some()),
        ("--compare-dir", a.compare_dir.is_some()),
    ] {
        if given {
            return Err(refused(flag, "the Python functions write no files: validate() returns the report"));
        }
    }
    let (saved, _, comparisons) =
        py.detach(|| greybox::cli::validate::compare(&a)).map_err(words::<ValidateArgs>("validate"))?;
    Ok(greybox::cli::validate::to_json(&saved, &comparisons))
}

/// One observer run: its name, its final estimates `(k_e, k_t, r_s, k_e_se, r_s_se)` (the
/// standard errors `None` for the MRAS) and its trajectory as a pyarrow RecordBatch
/// `t [s], k_e [V s/rad], r_s [Ω]` (with `--estimator ekf` also `k_e_se`, `r_s_se`; with
/// `--t0` the temperatures `t_winding`, `t_magnet` [°C] and their standard errors [K]).
type Run = (String, (f64, f64, f64, Option<f64>, Option<f64>, Option<f64>), Py<PyAny>);

/// Runs the online estimator of `greybox track` (the flags `argv`) over each log, the GIL
/// released; every point of each trajectory, and the filter's innovation ratio (its
/// self-check, `greybox::online::INNOVATION_RATIO_LIMIT`).
///
/// Errors: `OptionError`, `DataError`, `FitError` with the command line's messages.
#[pyfunction]
pub fn track(py: Python<'_>, argv: Vec<String>) -> PyResult<Vec<Run>> {
    let a: TrackArgs = parse("track", &argv).map_err(from_clap)?;
    for (flag, given) in [("--json", a.json.is_some()), ("--plot", a.plot.is_some())] {
        if given {
            return Err(refused(
                flag,
                "the Python functions write no files: track() returns the trajectories",
            ));
        }
    }
    let thermal = greybox::cli::track::thermal(&a).map_err(words::<TrackArgs>("track"))?;
    let (runs, names) =
        py.detach(|| greybox::cli::track::track_logs(&a)).map_err(words::<TrackArgs>("track"))?;
    runs.into_iter()
        .zip(names)
        .map(|((_, _, tr), name)| {
            let f = &tr.final_estimate;
            let column = |v: Vec<f64>| Arc::new(Float64Array::from(v)) as ArrayRef;
            let mut columns = vec![
                ("t", column(tr.t.clone())),
                ("k_e", column(tr.k_e.clone())),
                ("r_s", column(tr.r_s.clone())),
            ];
            if !tr.k_e_se.is_empty() {
                columns.push(("k_e_se", column(tr.k_e_se.clone())));
                columns.push(("r_s_se", column(tr.r_s_se.clone())));
            }
            if let Some(reference) = &thermal {
                let temps = tr.temperatures(a.pole_pairs, reference);
                for (name, v) in [
                    ("t_winding", temps.t_winding),
                    ("t_winding_se", temps.t_winding_se),
                    ("t_magnet", temps.t_magnet),
                    ("t_magnet_se", temps.t_magnet_se),
                ] {
                    if !v.is_empty() {
                        columns.push((name, column(v)));
                    }
                }
            }
            let batch = RecordBatch::try_from_iter(columns)
                .map_err(|e| crate::errors::Error::new_err(e.to_string()))?;
            let se = tr.final_se();
            let last = (f.k_e, f.k_t, f.r_s, se.map(|s| s.0), se.map(|s| s.1), tr.innovation_ratio);
            Ok((name, last, batch.to_pyarrow(py)?.unbind()))
        })
        .collect()
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
