//! The result of a PMSM fit: the generic report, flattened into the same JSON object, and
//! what only a motor fit has (pole pairs, voltage hold and input, cable, the least-squares
//! start against the estimate, motor-specific advice).

use crate::estimate::FitResult;
use crate::estimate::ParameterEstimate;
use crate::pmsm::Scale;
use crate::pmsm::model::interval::{VoltageHold, VoltageInput};
use crate::pmsm::model::inverter::InverterModel;
use crate::report::eng::format_eng;
use crate::report::summary::REMARKS;
use crate::report::{Block, Document};
use serde::{Deserialize, Serialize};

/// The least-squares start against the prediction-error estimate of one parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StartComparison {
    /// Parameter name.
    pub name: String,
    /// Least-squares estimate \[unit\].
    pub least_squares: f64,
    /// Prediction-error estimate \[unit\].
    pub pem: f64,
    /// `100 (LS − PEM)/PEM` \[%\]: the bias of LS if PEM is right.
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
    /// The known series (cable) resistance taken out of `r_s` \[Ω\].
    pub cable_resistance: f64,
    /// The inverter model the fit used (its `v_dt` is among the parameters).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inverter: Option<InverterModel>,
    /// The PWM inverter the fit resolved (its `t_d`, `u_th` are among the parameters; the
    /// carrier's first edge as chosen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pwm: Option<crate::pmsm::model::pwm::PwmInverter>,
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
    /// Whether the steady-state equations were fitted ([`crate::pmsm::steady_state`], chosen
    /// for a log the dynamic model cannot resolve or whose voltage is point-sampled, or asked
    /// for), not the dynamic model: such a fit simulates no currents.
    pub fn steady_state(&self) -> bool {
        self.report.model.ends_with("_steady")
    }

    /// The estimate as the start of a fit with the inverter model: the values of `model`'s
    /// parameters, then `v_dt` \[SI units\]; `None` when one of them was not estimated.
    pub(crate) fn inverter_start(&self, model: crate::pmsm::model::kind::MotorKind) -> Option<Vec<f64>> {
        let nuisance = match &self.pwm {
            Some(p) => p.parameter_names(),
            None => vec!["v_dt"],
        };
        let names = model.parameter_names().iter().copied().chain(nuisance);
        names.map(|n| self.parameter(n).map(|p| p.value)).collect()
    }
    /// The JSON report (pretty-printed; non-finite numbers as `null`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

/// What the report of a PMSM fit says that the data cannot tell: how the log's currents
/// were scaled (the fit itself always works in peak values).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReportOptions {
    /// Scaling of the log's current columns (`--current-scale`): with
    /// [`Scale::Rms`] the report adds `k_t` per RMS ampere.
    pub current_scale: Scale,
}

/// The conventions of a PMSM report in words (MODEL.md §1–2): amplitude-invariant dq in
/// peak values, `k_e` as line-to-line RMS back-EMF per mechanical rad/s, `k_t` per peak
/// ampere, and per RMS ampere when the log's currents were RMS. `k_e`, `k_t` \[SI\] are the
/// estimates, quoted in the other units data sheets use; `salient` adds the IPM's
/// reluctance torque.
pub fn conventions(k_e: Option<f64>, k_t: Option<f64>, salient: bool, options: ReportOptions) -> Vec<String> {
    let mut out = vec![
        "dq: amplitude-invariant Clarke/Park in peak values (|i_dq| = phase peak current, |u_dq| = phase peak \
         voltage; MODEL.md §1); speeds and angles mechanical unless marked _e"
            .to_string(),
    ];
    let per_krpm = |k: f64| k * 1000.0 * std::f64::consts::PI / 30.0;
    out.push(format!(
        "k_e: line-to-line RMS back-EMF per mechanical rad/s [V s/rad], k_e = √(3/2) n_p ψ_f{}",
        k_e.map_or(String::new(), |k| format!(" ({:.4} V line-to-line RMS per 1000 rpm)", per_krpm(k)))
    ));
    out.push(format!(
        "k_t: torque per ampere of peak phase current (= |i_dq|) [N m/A], k_t = √(3/2) k_e = 1.5 n_p ψ_f{}",
        if salient {
            " (magnet torque; the reluctance torque 1.5 n_p (l_d − l_q) i_d i_q comes on top)"
        } else {
            ""
        }
    ));
    if options.current_scale == Scale::Rms {
        out.push(format!(
            "the log's currents were RMS (--current-scale rms, multiplied by √2 on reading): per RMS ampere \
             k_t = √2 × k_t{}",
            k_t.map_or(String::new(), |k| format!(" = {:.6} N m/A", std::f64::consts::SQRT_2 * k))
        ));
    }
    out.push("psi_f: magnet flux linkage, peak per phase [V s]".into());
    out.push(
        "ratings: k_t_rms = √2 k_t per ampere of RMS phase current [N m/A]; k_v = 60/(2π √2 k_e) mechanical rpm \
         per volt of peak line-to-line back-EMF [rpm/V] (ODrive/VESC: k_t = 8.27/k_v); k_m = k_t/√(1.5 r_s) = \
         k_e/√r_s, torque per √W of copper loss 3 r_s I_rms² [N m/√W]"
            .into(),
    );
    out
}

impl PmsmFit {
    /// The report as a document: the machine and its input, the generic report with the
    /// conventions in words, the least-squares start against the estimate, remarks.
    pub fn document(&self, options: ReportOptions) -> Document {
        let mut d = Document::default();
        let kind = if self.report.model.starts_with("pmsm_ipm") {
            "interior magnets (ipm)"
        } else {
            "surface magnets (spm)"
        };
        d.line(if self.steady_state() {
            format!(
                "PMSM, {kind}, {} pole pairs, steady-state equations on the {}",
                self.pole_pairs, self.input
            )
        } else {
            format!(
                "PMSM, {kind}, {} pole pairs, {} voltage hold, driven by the {}",
                self.pole_pairs, self.hold, self.input
            )
        });
        if self.cable_resistance != 0.0 {
            d.line(format!(
                "known cable resistance {} in series, not part of r_s",
                format_eng(self.cable_resistance, "ohm", 4)
            ));
        }
        let value = |n: &str| self.report.parameter(n).map(|p| p.value);
        let k_t = self.report.derived("k_t").map(|q| q.value);
        let salient = self.report.parameter("l_d").is_some();
        d.extend(self.report.document(&conventions(value("k_e"), k_t, salient, options)));
        let more =
            !(self.start_comparison.is_empty() && self.pmsm_advice.is_empty() && self.pmsm_notes.is_empty());
        let has_remarks = d.blocks.iter().any(|b| matches!(b, Block::Heading(h) if h == REMARKS));
        if more && !has_remarks {
            d.heading(REMARKS);
        }
        if !self.start_comparison.is_empty() {
            let parts: Vec<String> = self
                .start_comparison
                .iter()
                .map(|c| format!("{} {:+.4} %", c.name, c.difference_percent))
                .collect();
            d.line(format!(
                "least-squares start vs estimate (LS bias if the fit is right): {}",
                parts.join(", ")
            ));
        }
        self.pmsm_advice.iter().for_each(|a| d.line(format!("advice: {a}")));
        self.pmsm_notes.iter().for_each(|n| d.line(format!("note: {n}")));
        d
    }
}

/// The report table with peak-scaled currents ([`PmsmFit::document`] as plain text).
impl std::fmt::Display for PmsmFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.document(ReportOptions::default()).to_text())
    }
}

/// The computational delay of a reference input as a nuisance entry of the report's
/// parameters (`delay_samples` \[samples\]); `None` for the terminal voltage. Held fixed at the
/// given delay unless `estimated` gives the 95 % set of delays `[lo, hi]` a likelihood-ratio
/// test does not reject (see [`crate::pmsm::fit::input_search`]); its standard error is then
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
        std_error_white: (ci[1] - ci[0]) / 3.92,
        ci95: ci,
        error_index_percent: f64::NAN,
        fixed: estimated.is_none(),
        nuisance: true,
        at_bound: false,
        experiment: None,
        start: d,
    })
}

/// The estimates of a fit as text, one line per estimate: name, value, standard error, 95 %
/// interval (or "at its bound"), unit, and the log of a per-log estimate; then the derived
/// quantities.
pub fn estimate_table(result: &FitResult) -> String {
    let mut t = format!("{:<8} {:>14} {:>12} {:>30}\n", "", "value", "std error", "95 % interval");
    for p in &result.parameters {
        let interval = if p.at_bound {
            "at its bound".to_string()
        } else {
            format!("[{:.6e}, {:.6e}]", p.ci95[0], p.ci95[1])
        };
        let se = if p.at_bound { "-".to_string() } else { format!("{:.3e}", p.std_error) };
        let log = p.experiment.as_ref().map_or(String::new(), |e| format!("  (log {e})"));
        t += &format!("{:<8} {:>14.6e} {:>12}   {interval}  {}{log}\n", p.name, p.value, se, p.unit);
    }
    for d in &result.derived {
        t += &format!("{:<8} {:>14.6e} {:>12.3e}   {}\n", d.name, d.value, d.std_error, d.unit);
    }
    t
}
