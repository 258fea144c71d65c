//! `greybox.simulate`: Python keywords to the application layer's typed
//! [`SimulateRequest`] (each converted once, a wrong one refused naming the keyword), the
//! drive simulated by [`greybox::drive::simulate_drive`] with the GIL released.

use crate::errors::to_py;
use crate::keyword::each;
use crate::reading::Keywords;
use crate::words::in_python_words;
use arrow_pyarrow::ToPyArrow;
use greybox::app::{SimulateRequest, drive_config};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// The keywords of `simulate`.
const SIMULATE: Keywords = Keywords {
    command: "simulate",
    doc: "docs/cli.md",
    example: "scenario=\"exp3\"",
    own: SIMULATE_KEYWORDS,
    reading: false,
    outputs: &["output", "print_config"],
    returns: "simulate() returns the log",
};

/// The keywords of `simulate`'s own options, in the order `greybox simulate --help` lists
/// their flags.
const SIMULATE_KEYWORDS: &[&str] = &[
    "scenario",
    "config",
    "motor",
    "seed",
    "duration",
    "set",
    "inverter",
    "t_d",
    "u_th",
    "leg_state_width",
    "pwm_levels",
];

/// Simulates the closed-loop drive of `greybox simulate` with the keyword `options`
/// (`scenario` or `config`, `motor`, `seed`, `duration`, `set` as `PATH=VALUE` texts, the
/// switching-resolved inverter's), the GIL released: the log as a pyarrow RecordBatch (time
/// column `t` [s], then the channels, as the written Parquet/Arrow log) and the truth as
/// JSON (the `.truth.json` file's).
///
/// Errors: `OptionError` naming the keyword for an unknown scenario or field or a bad
/// value, `FitError` for a diverging simulation.
#[pyfunction]
pub fn simulate(py: Python<'_>, options: &Bound<'_, PyDict>) -> PyResult<(Py<PyAny>, String)> {
    let mut r = SimulateRequest::default();
    each(options, |x| {
        match x.key {
            "scenario" => r.scenario = Some(x.text()?),
            "config" => r.config = Some(PathBuf::from(x.text()?)),
            "motor" => r.motor = x.choice()?,
            "seed" => r.seed = Some(x.count()?),
            "duration" => r.duration = Some(x.number()?),
            "set" => r.set = x.texts()?,
            "inverter" => r.inverter = x.choice()?,
            "t_d" => r.t_d = x.number()?,
            "u_th" => r.u_th = x.number()?,
            "leg_state_width" => r.leg_state_width = x.number()?,
            "pwm_levels" => r.pwm_levels = x.count()?,
            other => return Err(SIMULATE.not_taken(other)),
        }
        Ok(())
    })?;
    let words = |e| to_py(in_python_words(e));
    let cfg = drive_config(&r).map_err(words)?;
    let log = py.detach(|| greybox::drive::simulate_drive(&cfg)).map_err(words)?;
    let batch = greybox::data::to_record_batch(&log.experiment, "t").map_err(to_py)?;
    let truth =
        serde_json::to_string_pretty(&log.truth).map_err(|e| crate::errors::Error::new_err(e.to_string()))?;
    Ok((batch.to_pyarrow(py)?.unbind(), truth))
}
