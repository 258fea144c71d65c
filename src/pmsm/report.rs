//! The result of a PMSM fit: the generic report, flattened into the same JSON object, and
//! what only a motor fit has (pole pairs, voltage hold and input, cable, the least-squares
//! start against the estimate, motor-specific advice).

use super::interval::{VoltageHold, VoltageInput};
use super::inverter::InverterModel;
use crate::estimate::FitResult;
use crate::estimate::ParameterEstimate;
use serde::{Deserialize, Serialize};

/// The least-squares start against the prediction-error estimate of one parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StartComparison {
    /// Parameter name.
    pub name: String,
    /// Least-squares estimate [unit].
    pub least_squares: f64,
    /// Prediction-error estimate [unit].
    pub pem: f64,
    /// `100 (LS − PEM)/PEM` [%]: the bias of LS if PEM is right.
    pub difference_percent: f64,
}

/// A PMSM fit: the generic report (flattened into the same JSON object) and what only a
/// motor fit has: pole pairs, the voltage hold and how it was chosen, the least-squares
/// start against the estimate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PmsmFit {
    /// The prediction-error fit with the chosen hold.
    #[serde(flatten)]
    pub report: FitResult,
    /// Pole pairs n_p.
    pub pole_pairs: u32,
    /// The voltage hold of the reported fit.
    pub hold: VoltageHold,
    /// The voltage that drove the model.
    pub input: VoltageInput,
    /// The known series (cable) resistance taken out of `r_s` [Ω].
    pub cable_resistance: f64,
    /// The inverter model the fit used (its `v_dt` is among the parameters).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inverter: Option<InverterModel>,
    /// Loss of every hold fitted, in fitting order.
    pub hold_losses: Vec<(VoltageHold, f64)>,
    /// The least-squares start against the estimate, when the fit started from LS.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub start_comparison: Vec<StartComparison>,
    /// Motor-specific advice (e.g. an ambiguous voltage hold).
    pub pmsm_advice: Vec<String>,
    /// Motor-specific remarks (start, hold selection).
    pub pmsm_notes: Vec<String>,
}

impl std::ops::Deref for PmsmFit {
    type Target = FitResult;
    fn deref(&self) -> &FitResult {
        &self.report
    }
}

impl PmsmFit {
    /// The JSON report (pretty-printed; non-finite numbers as `null`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

impl std::fmt::Display for PmsmFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "PMSM with {} pole pairs, {} voltage hold, driven by the {}",
            self.pole_pairs, self.hold, self.input
        )?;
        if self.cable_resistance != 0.0 {
            writeln!(f, "known cable resistance {} ohm in series, not part of r_s", self.cable_resistance)?;
        }
        write!(f, "{}", self.report)?;
        if !self.start_comparison.is_empty() {
            let parts: Vec<String> = self
                .start_comparison
                .iter()
                .map(|c| format!("{} {:+.4} %", c.name, c.difference_percent))
                .collect();
            writeln!(
                f,
                "least-squares start vs estimate (LS bias if the fit is right): {}",
                parts.join(", ")
            )?;
        }
        for a in &self.pmsm_advice {
            writeln!(f, "advice: {a}")?;
        }
        for n in &self.pmsm_notes {
            writeln!(f, "note: {n}")?;
        }
        Ok(())
    }
}

/// The computational delay of a reference input as a nuisance entry of the report's
/// parameters (`delay_samples` [samples]); `None` for the terminal voltage. Held fixed at the
/// given delay unless `estimated` gives the 95 % set of delays `[lo, hi]` a likelihood-ratio
/// test does not reject (see [`super::input_search`]); its standard error is then
/// `(hi − lo)/3.92` (0 when the set is the delay alone) and its error index is not defined.
pub(crate) fn delay_parameter(
    input: VoltageInput,
    estimated: Option<[usize; 2]>,
) -> Option<ParameterEstimate> {
    let VoltageInput::Reference { delay, .. } = input else { return None };
    let d = delay as f64;
    let ci = estimated.map_or([d, d], |[lo, hi]| [lo as f64, hi as f64]);
    Some(ParameterEstimate {
        name: "delay_samples".into(),
        unit: "samples".into(),
        value: d,
        std_error: (ci[1] - ci[0]) / 3.92,
        ci95: ci,
        error_index_percent: f64::NAN,
        fixed: estimated.is_none(),
        nuisance: true,
        at_bound: false,
        experiment: None,
        start: d,
    })
}
