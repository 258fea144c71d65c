//! Validation of a saved PMSM fit on logs it was not fitted on: the model and parameters
//! are read back from the JSON report of [`crate::pmsm::fit_pmsm`] (or of the command line's
//! `greybox fit --json`) and compared with each log by [`crate::report::compare()`].

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::model::interval::{VoltageHold, VoltageInput};
use crate::pmsm::model::inverter::InverterModel;
use crate::pmsm::model::ipm::PmsmIpm;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::model::spm::PmsmSpm;
use crate::report::{Comparison, compare};
use serde::Deserialize;

/// The model of a saved fit: motor kind, pole pairs, voltage hold and parameter values.
#[derive(Clone, Debug, PartialEq)]
pub struct SavedModel {
    /// Surface or interior magnets.
    pub kind: MotorKind,
    /// Pole pairs n_p.
    pub pole_pairs: u32,
    /// The voltage hold of the fit.
    pub hold: VoltageHold,
    /// The voltage that drove the model (terminal, or the reference with its delay).
    pub input: VoltageInput,
    /// The known series (cable) resistance the fit took out of `r_s` \[Ω\].
    pub cable_resistance: f64,
    /// The inverter model of the fit, if it had one.
    pub inverter: Option<InverterModel>,
    /// Parameter values, model order of `kind`, then `v_dt` with the inverter model (SI
    /// units).
    pub theta: Vec<f64>,
    /// Number of estimated (not fixed) parameters.
    pub n_estimated: usize,
}

#[derive(Deserialize)]
struct Report {
    model: String,
    pole_pairs: Option<u32>,
    hold: Option<VoltageHold>,
    #[serde(default)]
    input: VoltageInput,
    #[serde(default)]
    cable_resistance: f64,
    #[serde(default)]
    inverter: Option<InverterModel>,
    parameters: Vec<Saved>,
}

#[derive(Deserialize)]
struct Saved {
    name: String,
    value: f64,
    #[serde(default)]
    fixed: bool,
    #[serde(default)]
    experiment: Option<String>,
}

impl SavedModel {
    /// Reads a fit report (JSON text). `pole_pairs` and `hold` override or supply what the
    /// report lacks (a least-squares report carries neither; the hold then defaults to the
    /// stator frame).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `params`) for text that is not a report, a model
    /// other than `pmsm_spm`/`pmsm_ipm` (and their `_least_squares` variants), a missing
    /// parameter, parameters estimated per log (name the log with a report of one fit), or
    /// no pole-pair number; [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError::InvalidPolePairs) for 0.
    pub fn from_json(text: &str, pole_pairs: Option<u32>, hold: Option<VoltageHold>) -> Result<Self> {
        let bad = |reason: String| Error::InvalidOption { option: "params".into(), reason };
        let r: Report = serde_json::from_str(text).map_err(|e| bad(format!("not a fit report: {e}")))?;
        let base = r.model.strip_suffix("_least_squares").unwrap_or(&r.model);
        let kind = [MotorKind::Spm, MotorKind::Ipm]
            .into_iter()
            .find(|k| k.model_name() == base)
            .ok_or_else(|| bad(format!("model `{}` is not a PMSM model (pmsm_spm, pmsm_ipm)", r.model)))?;
        if let Some(p) = r.parameters.iter().find(|p| p.experiment.is_some()) {
            return Err(bad(format!(
                "`{}` was estimated per log; validation needs one value per parameter",
                p.name
            )));
        }
        let nuisance = r.inverter.map(|_| "v_dt");
        let theta = kind
            .parameter_names()
            .iter()
            .chain(nuisance.iter())
            .map(|n| {
                r.parameters
                    .iter()
                    .find(|p| p.name == *n)
                    .map(|p| p.value)
                    .ok_or_else(|| bad(format!("the report has no parameter `{n}`")))
            })
            .collect::<Result<Vec<f64>>>()?;
        let pole_pairs = pole_pairs
            .or(r.pole_pairs)
            .ok_or_else(|| bad("the report gives no pole pairs: pass them (-p)".into()))?;
        crate::pmsm::log::signals::check_pole_pairs(pole_pairs)?;
        Ok(Self {
            kind,
            pole_pairs,
            hold: hold.or(r.hold).unwrap_or_default(),
            input: r.input,
            cable_resistance: r.cable_resistance,
            inverter: r.inverter,
            theta,
            n_estimated: r.parameters.iter().filter(|p| !p.fixed).count(),
        })
    }

    /// The setup of the saved model: pole pairs, hold, voltage input, cable, inverter.
    pub fn setup(&self) -> PmsmSetup {
        PmsmSetup {
            input: self.input,
            cable_resistance: self.cable_resistance,
            inverter: self.inverter,
            ..PmsmSetup::new(self.pole_pairs, self.hold)
        }
    }

    /// Compares the model, as the fit had it (voltage input, cable, inverter), with each
    /// experiment, simulated from its measured first current.
    ///
    /// # Errors
    /// Those of [`compare()`]: a log without the channels the model reads, a diverging
    /// simulation.
    pub fn validate(&self, experiments: &[Experiment]) -> Result<Vec<Comparison>> {
        let setup = self.setup();
        experiments
            .iter()
            .map(|e| match self.kind {
                MotorKind::Spm => compare(&PmsmSpm::from_setup(setup), e, &self.theta, self.n_estimated),
                MotorKind::Ipm => compare(&PmsmIpm::from_setup(setup), e, &self.theta, self.n_estimated),
            })
            .collect()
    }
}
