//! Planned experiments on the simulated drive: a [`DriveConfig`] (scenario or file) is the
//! plan; one noise-free simulation and one normal-equation pass of the model the fit would
//! use ([`crate::estimate::design::predict`]) predict every parameter's standard error,
//! interval, correlations and the optimality criteria, so that plans can be compared and
//! ranked before anything is run (issue 32).
//!
//! The prediction is for [`crate::pmsm::fit_pmsm`] with its defaults on the terminal
//! voltage (output error, free initial currents, the stator hold the simulator steps by);
//! voltage and speed noise are not in it (they enter the model's inputs: errors in
//! variables, a bias and a spread this bound does not show).

use super::config::DriveConfig;
use super::plan::LimitUse;
use super::sim::simulate_drive;
use crate::error::Result;
use crate::estimate::design::{DesignOptions, Prediction, predict};
use crate::model::GreyBoxModel;
use crate::pmsm::{PmsmIpm, PmsmSetup, PmsmSpm, VoltageHold};
use serde::{Deserialize, Serialize};

/// The dq-current noise variance per phase-current variance, `4/3`: two measured phases
/// with `i_c = −i_a − i_b`, amplitude-invariant Clarke (`Var α = σ²`, `Var β = 5σ²/3`),
/// averaged over the electrical angle by the Park rotation.
pub const DQ_PER_PHASE_VARIANCE: f64 = 4.0 / 3.0;

/// A plan's prediction (JSON: one entry of `greybox design --json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanPrediction {
    /// Plan name (the scenario's or the file's).
    pub plan: String,
    /// Record length \[s\].
    pub duration: f64,
    /// Phase-current noise σ \[A\] and its AR(1) pole the prediction assumed.
    pub current_noise: f64,
    /// AR(1) pole of the current noise.
    pub current_noise_pole: f64,
    /// The prediction.
    pub prediction: Prediction,
    /// How much of the current and voltage limits the noise-free run used.
    pub limits: LimitUse,
}

/// Predicts the uncertainty of [`crate::pmsm::fit_pmsm`] on the drive `cfg` (its motor is
/// the nominal θ, its `sensors.current_noise` and pole the noise; σ > 0 is required), and
/// how much of the drive's current and voltage limits the plan uses ([`LimitUse`]).
///
/// # Errors
/// Those of [`simulate_drive`] and [`predict`] (a zero current noise is an
/// [`crate::Error::InvalidOption`] naming `sensors.current_noise`).
pub fn predict_plan(cfg: &DriveConfig) -> Result<PlanPrediction> {
    if !(cfg.sensors.current_noise.is_finite() && cfg.sensors.current_noise > 0.0) {
        return Err(crate::Error::InvalidOption {
            option: "sensors.current_noise".into(),
            reason: format!(
                "{} A: the prediction needs the phase-current noise σ > 0 (a noise-free fit has no spread)",
                cfg.sensors.current_noise
            ),
        });
    }
    let mut clean = cfg.clone();
    clean.sensors = super::config::Sensors::default();
    let log = simulate_drive(&clean)?;
    let limits = LimitUse::of(&log.experiment, cfg)?;
    let s = &cfg.sensors;
    let sd = (DQ_PER_PHASE_VARIANCE).sqrt() * s.current_noise;
    let options =
        DesignOptions { noise_sd: vec![sd, sd], noise_pole: s.current_noise_pole, ..Default::default() };
    let m = &cfg.motor;
    let setup = PmsmSetup::new(m.n_p, VoltageHold::Stator);
    let e = std::slice::from_ref(&log.experiment);
    let prediction = if m.salient() {
        let model = PmsmIpm::from_setup(setup);
        predict(&model, e, &theta(&model, m), &options)?
    } else {
        let model = PmsmSpm::from_setup(setup);
        predict(&model, e, &theta(&model, m), &options)?
    };
    Ok(PlanPrediction {
        plan: cfg.name.clone(),
        duration: cfg.duration,
        current_noise: s.current_noise,
        current_noise_pole: s.current_noise_pole,
        prediction,
        limits,
    })
}

/// The model's θ (by parameter name) from the motor; parameters it does not know keep
/// their nominal values.
fn theta<M: GreyBoxModel>(model: &M, m: &crate::pmsm::MotorParameters) -> Vec<f64> {
    model
        .parameters()
        .iter()
        .map(|p| match p.name.as_str() {
            "r_s" => m.r_s,
            "l_s" | "l_d" => m.l_d,
            "l_q" => m.l_q,
            "k_e" => m.k_e(),
            _ => p.nominal.unwrap_or(0.0),
        })
        .collect()
}
