//! What a user asks of a validation, typed ([`ValidateRequest`]): the options of `greybox
//! validate` and of the Python `validate` (MATLAB's `compare`), without their spelling and
//! without the outputs each writes; [`validate`] simulates a saved fit on each log.

use super::request::LogReading;
use crate::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::{CsvOptions, SavedModel, VoltageHold};
use crate::report::Comparison;
use std::path::PathBuf;

/// A validation as asked for: the saved fit, what its report may lack or what overrides
/// it, and how the logs are read.
#[derive(Clone, Debug, PartialEq)]
pub struct ValidateRequest {
    /// The JSON report of a fit (`greybox fit --json`).
    pub params: PathBuf,
    /// Pole pairs n_p, when the report does not give them (a least-squares report).
    pub pole_pairs: Option<u32>,
    /// The voltage hold, overriding the report's.
    pub hold: Option<VoltageHold>,
    /// How the logs are read (segments with `split_gaps`, each compared on its own).
    pub reading: LogReading,
}

impl ValidateRequest {
    /// The command line's defaults for the report `params`.
    pub fn new(params: PathBuf) -> Self {
        Self { params, pole_pairs: None, hold: None, reading: LogReading::default() }
    }
}

/// The saved fit of `r.params`, the logs of `logs` read as `r` asks, and the comparison of
/// the fit's simulation with each log (fit %, residuals, whiteness, FPE, AIC; Ljung 1999,
/// §16.6), as `greybox validate` computes them.
///
/// # Errors
/// An unreadable or invalid report ([`Error::Io`], those of [`SavedModel::from_json`]), an
/// unreadable log, a simulation that fails.
pub fn validate(
    logs: &[PathBuf],
    r: &ValidateRequest,
) -> Result<(SavedModel, Vec<Experiment>, Vec<Comparison>)> {
    let text =
        std::fs::read_to_string(&r.params).map_err(|source| Error::Io { path: r.params.clone(), source })?;
    let saved = SavedModel::from_json(&text, r.pole_pairs, r.hold)?;
    let csv = CsvOptions { pole_pairs: Some(saved.pole_pairs), ..r.reading.csv.clone() };
    let logs: Vec<_> =
        super::read_logs(logs, &csv, r.reading.split_gaps, false)?.into_iter().flatten().collect();
    let comparisons = saved.validate(&logs)?;
    Ok((saved, logs, comparisons))
}

/// The JSON of a validation (`greybox validate --json`): model, pole pairs, hold, θ and each
/// log's metrics.
pub fn validation_json(saved: &SavedModel, comparisons: &[Comparison]) -> String {
    let metrics: Vec<serde_json::Value> = comparisons
        .iter()
        .map(|c| serde_json::json!({ "experiment": c.experiment, "metrics": c.metrics }))
        .collect();
    let report = serde_json::json!({
        "model": saved.kind.model_name(),
        "pole_pairs": saved.pole_pairs,
        "hold": saved.hold,
        "theta": saved.theta,
        "comparisons": metrics,
    });
    serde_json::to_string_pretty(&report).unwrap_or_default()
}
