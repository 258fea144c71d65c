//! `greybox.track`: Python keywords to the application layer's typed [`TrackRequest`]
//! (each converted once, by the command line's words, a wrong one refused naming the
//! keyword), the estimator run over each log by [`greybox::app::track_logs`] with the GIL
//! released, and the trajectories handed back as pyarrow record batches.

use crate::errors::{OptionError, to_py};
use crate::keyword::each;
use crate::reading::{Keywords, ReadingKeys};
use crate::words::in_python_words;
use arrow_array::{ArrayRef, Float64Array, RecordBatch};
use arrow_pyarrow::ToPyArrow;
use greybox::app::{TrackRequest, track_logs};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Arc;

/// The keywords of `track` that set the estimation, besides the reading's
/// ([`crate::reading::READING_KEYWORDS`]), in the order `greybox track --help` lists their flags.
pub const TRACK_KEYWORDS: &[&str] = &[
    "pole_pairs",
    "l_s",
    "l_q",
    "params",
    "k_e0",
    "r_s0",
    "gamma_ke",
    "gamma_rs",
    "i_d_threshold",
    "observer_gain",
    "adaptation",
    "tau_ke",
    "tau_rs",
    "hold",
    "estimator",
    "current_noise",
    "r_s_walk",
    "k_e_walk",
    "t0",
    "r_s_t0",
    "psi_f_t0",
];

/// The keywords of `track`.
const TRACK: Keywords = Keywords {
    command: "track",
    doc: "docs/cli.md",
    example: "l_s=5e-3",
    own: TRACK_KEYWORDS,
    reading: true,
    outputs: &["json", "plot", "max_points", "quiet"],
    returns: "track() returns the trajectories",
};

/// The request of `options` (keyword → value; `None` values are left at their default),
/// from the command line's defaults, `pole_pairs` required.
///
/// Errors: `OptionError` naming the keyword: unknown, a file output, a bad value.
fn track_request(options: &Bound<'_, PyDict>) -> PyResult<TrackRequest> {
    let mut r = TrackRequest::new(0);
    let mut pole_pairs = false;
    let mut reading = ReadingKeys::new(r.reading.csv.clone());
    each(options, |x| {
        let number = || x.number().map(Some);
        match x.key {
            "pole_pairs" => {
                r.pole_pairs = x.count()?;
                pole_pairs = true;
            }
            "l_s" => r.l_s = number()?,
            "l_q" => r.l_q = number()?,
            "params" => r.params = Some(PathBuf::from(x.text()?)),
            "k_e0" => r.k_e0 = number()?,
            "r_s0" => r.r_s0 = number()?,
            "gamma_ke" => r.mras.gamma_ke = number()?,
            "gamma_rs" => r.mras.gamma_rs = number()?,
            "i_d_threshold" => r.mras.i_d_threshold = number()?,
            "observer_gain" => r.mras.observer_gain = number()?,
            "adaptation" => r.mras.adaptation = Some(x.choice()?),
            "tau_ke" => r.mras.tau_ke = number()?,
            "tau_rs" => r.mras.tau_rs = number()?,
            "hold" => r.hold = Some(x.choice()?),
            "estimator" => r.estimator = x.choice()?,
            "current_noise" => r.kalman.current_noise = number()?,
            "r_s_walk" => r.kalman.r_s_walk = number()?,
            "k_e_walk" => r.kalman.k_e_walk = number()?,
            "t0" => r.t0 = number()?,
            "r_s_t0" => r.r_s_t0 = number()?,
            "psi_f_t0" => r.psi_f_t0 = number()?,
            other if reading.take(other, x)? => {}
            other => return Err(TRACK.not_taken(other)),
        }
        Ok(())
    })?;
    if !pole_pairs {
        return Err(OptionError::new_err("pole_pairs: required (a whole number)"));
    }
    r.reading = reading.finish()?;
    Ok(r)
}

/// One estimator run: its name, its final estimates `(k_e, k_t, r_s, k_e_se, r_s_se,
/// innovation_ratio)` (the standard errors `None` for the MRAS) and its trajectory as a
/// pyarrow RecordBatch `t [s], k_e [V s/rad], r_s [Ω]` (with the Kalman filter also
/// `k_e_se`, `r_s_se`; with `t0` the temperatures `t_winding`, `t_magnet` [°C] and their
/// standard errors [K]).
type Run = (String, (f64, f64, f64, Option<f64>, Option<f64>, Option<f64>), Py<PyAny>);

/// Runs the online estimator asked for by the keyword `options` (the flags of `greybox
/// track` as keywords: `estimator="mras"`) over each of `logs`, the GIL released; every
/// point of each trajectory, and its self-check's ratio
/// (`greybox::online::INNOVATION_RATIO_LIMIT`).
///
/// Errors: `OptionError` naming the keyword, `DataError`, `FitError` (an estimator that
/// fails on a log).
#[pyfunction]
pub fn track(py: Python<'_>, logs: Vec<PathBuf>, options: &Bound<'_, PyDict>) -> PyResult<Vec<Run>> {
    let r = track_request(options)?;
    let thermal = r.thermal().map_err(|e| to_py(in_python_words(e)))?;
    let (runs, names) = py.detach(|| track_logs(&logs, &r)).map_err(|e| to_py(in_python_words(e)))?;
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
                let temps = tr.temperatures(r.pole_pairs, reference);
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
