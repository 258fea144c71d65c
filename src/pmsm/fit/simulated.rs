//! The fitted model simulated on the logs it was fitted on: measured against simulated
//! currents per log, the data of the fit plot and the residual export
//! ([`crate::report::residuals`]).
//!
//! Each log is predicted as the fit predicted it (simulated, or k steps ahead with the
//! fit's horizon; a dead-time mask's periods flagged as not counted) at its own θ̂ (shared
//! parameters, and its copy of the per-log ones) from its estimated initial state (the
//! measured first currents when the fit took them as exact), with the fit's hold, voltage
//! input, cable and inverter model; a fit through the PWM inverter as its one-step
//! predictor ([`PmsmPwm`]), the carrier's unknown first samples not counted.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::model::ipm::PmsmIpm;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::pwm::PmsmPwm;
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::model::spm::PmsmSpm;
use crate::report::{Comparison, compare_predicted};

/// What simulating a fit on its logs takes: the model kind and setup, each log's θ and
/// initial state, and the number of estimated parameters.
type Plan = (MotorKind, PmsmSetup, Vec<(Vec<f64>, Option<Vec<f64>>)>, usize);

impl PmsmFit {
    /// Measured against simulated outputs (`id`, `iq` \[A\]) of each of `experiments`, which
    /// must be the logs of the fit in the fit's order, one [`Comparison`] per log.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `experiments`) when their number differs from the
    /// fit's, the report is not a PMSM prediction-error fit, or a model parameter is
    /// missing from it; those of [`compare_predicted`] (a log without the channels the model reads, a diverging simulation).
    pub fn comparisons(&self, experiments: &[Experiment]) -> Result<Vec<Comparison>> {
        let (kind, setup, logs, n_params) = self.plan(experiments)?;
        let horizon = self.report.fit.horizon;
        experiments
            .iter()
            .zip(logs)
            .map(|(log, (theta, x0))| {
                let counted =
                    crate::pmsm::model::inverter::counted(self.inverter.as_ref(), self.pole_pairs, log);
                let x0 = x0.as_deref();
                if let Some(pwm) = self.pwm {
                    let m = PmsmPwm::new(setup, kind, pwm);
                    let counted = pwm_counted(&m, self.input, log, &theta)?;
                    return compare_predicted(&m, log, &theta, x0, n_params, None, counted);
                }
                match kind {
                    MotorKind::Spm => {
                        let m = PmsmSpm::from_setup(setup);
                        compare_predicted(&m, log, &theta, x0, n_params, horizon, counted)
                    }
                    MotorKind::Ipm => {
                        let m = PmsmIpm::from_setup(setup);
                        compare_predicted(&m, log, &theta, x0, n_params, horizon, counted)
                    }
                }
            })
            .collect()
    }

    /// The simulated outputs alone of [`comparisons`](Self::comparisons), row-major
    /// `N × n_y` per log (`[k n_y + i]`), without the measured copy and the metrics.
    ///
    /// # Errors
    /// As [`comparisons`](Self::comparisons).
    pub fn simulated_outputs(&self, experiments: &[Experiment]) -> Result<Vec<Vec<f64>>> {
        fn run<M: crate::model::GreyBoxModel>(
            m: &M,
            e: &Experiment,
            theta: &[f64],
            x0: Option<&[f64]>,
        ) -> Result<Vec<f64>> {
            let prep = crate::model::Prepared::new(m, e)?;
            crate::simulate::simulate(
                m,
                &prep,
                theta,
                &crate::simulate::SimOptions { x0, ..Default::default() },
            )
        }
        let (kind, setup, logs, _) = self.plan(experiments)?;
        experiments
            .iter()
            .zip(logs)
            .map(|(log, (theta, x0))| match (self.pwm, kind) {
                (Some(pwm), _) => run(&PmsmPwm::new(setup, kind, pwm), log, &theta, x0.as_deref()),
                (None, MotorKind::Spm) => run(&PmsmSpm::from_setup(setup), log, &theta, x0.as_deref()),
                (None, MotorKind::Ipm) => run(&PmsmIpm::from_setup(setup), log, &theta, x0.as_deref()),
            })
            .collect()
    }

    /// The [`Plan`] of simulating this fit on `experiments`.
    fn plan(&self, experiments: &[Experiment]) -> Result<Plan> {
        let bad = |reason: String| Error::InvalidOption { option: "experiments".into(), reason };
        let n = self.experiments.len();
        if experiments.len() != n {
            return Err(bad(format!("{} logs given, the fit has {n}", experiments.len())));
        }
        let kind = [MotorKind::Spm, MotorKind::Ipm]
            .into_iter()
            .find(|k| k.model_name() == self.model)
            .ok_or_else(|| bad(format!("model `{}` is not a PMSM prediction-error fit", self.model)))?;
        let mut names: Vec<&str> = kind.parameter_names().to_vec();
        if self.inverter.is_some() {
            names.push("v_dt");
        }
        if let Some(pwm) = &self.pwm {
            names.extend(pwm.parameter_names());
        }
        // Per-log copies follow each other in log order; a shared parameter has one entry.
        let theta_of = |e: usize| -> Result<Vec<f64>> {
            names
                .iter()
                .map(|name| {
                    let copies: Vec<f64> =
                        self.parameters.iter().filter(|p| p.name == *name).map(|p| p.value).collect();
                    match copies[..] {
                        [v] => Ok(v),
                        _ if copies.len() == n => Ok(copies[e]),
                        _ => Err(bad(format!(
                            "the report has {} values of `{name}` for {n} logs",
                            copies.len()
                        ))),
                    }
                })
                .collect()
        };
        let setup = PmsmSetup {
            input: self.input,
            cable_resistance: self.cable_resistance,
            inverter: self.inverter,
            ..PmsmSetup::new(self.pole_pairs, self.hold)
        };
        let n_params = self.parameters.iter().filter(|p| !p.fixed).count();
        let n_x = self.initial_states.len() / n.max(1);
        let logs = (0..n)
            .map(|e| {
                let x0 = (n_x == 2)
                    .then(|| self.initial_states[2 * e..2 * e + 2].iter().map(|p| p.value).collect());
                Ok((theta_of(e)?, x0))
            })
            .collect::<Result<_>>()?;
        Ok((kind, setup, logs, n_params))
    }
}

/// The samples a PWM fit counts on `log` at its estimate `theta`: all but the first, which
/// the fit weights out (the reference's delay, and the carrier's state before the log;
/// `pwm_start::SkipStart`), and, where the fit masked signs (a leg state not given), those
/// the sign mask's rule weights out at the estimate (`pwm_mask`; the fit took it at the
/// unmasked estimate, so the two sets may differ by a few samples).
///
/// # Errors
/// Those of the sign mask.
fn pwm_counted(
    m: &PmsmPwm,
    input: crate::pmsm::model::interval::VoltageInput,
    log: &Experiment,
    theta: &[f64],
) -> Result<Vec<bool>> {
    use crate::estimate::Weighting;
    let skip = super::pwm_start::SkipStart {
        inner: &crate::estimate::weighting::Uniform,
        skip: super::pwm_start::skipped(input),
    };
    if m.inverter().i_w.is_some() {
        return Ok((0..log.len()).map(|k| skip.sample_weight(log, k) > 0.0).collect());
    }
    let (mask, _) = super::pwm_mask::sign_mask(std::slice::from_ref(log), m, theta, &skip)?;
    Ok((0..log.len()).map(|k| mask.sample_weight(log, k) > 0.0).collect())
}
