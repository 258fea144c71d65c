//! The sign mask of a fit through the switching-resolved PWM inverter: the samples whose
//! period passes a phase current near zero at a piece's start are weighted out of the final
//! fit.
//!
//! Why: a leg state takes the sign of its phase current at each piece's start, and a wrong
//! sign during a blanking costs the leg `U_dc` for up to the dead time (a spike of
//! `U_dc t_d / L`, 0.2 A on the shared 3 µs log, where the rest of the residual is 1 mA).
//! Where the predicted current at such an instant is within its own error of zero, the sign
//! is a coin toss: the loss then jumps wherever a parameter's change turns a sign, its
//! minimum is decided by a few such samples, and the residual's size does not describe the
//! noise around the estimate. Measured on the shared PWM log at the true parameters
//! (`--pwm-levels 4096`): 18 samples of 72 000 carry 73 % of the loss; the continuation's fit
//! lands at twice the truth's loss and its parts disagree (Q's p ≤ 1e-7).
//!
//! So, after the continuation ([`super::pwm_start::continuation`]), the predictor at its
//! estimate gives each sample's residual and the smallest phase current at a piece's start
//! in the period before it, that period started from the previous period's prediction so
//! that the choice does not depend on the measured current's noise at the period's start
//! ([`PmsmPwm::sign_margins`]); a sample is weighted out when that
//! current is within [`MARGIN_SCALES`] × the residuals' trimmed rms of zero (the prediction's
//! error inside the period is of the residual's size; the trimmed rms leaves out the spikes
//! themselves, [`TRIMMED`]); so is a sample whose period holds a duty ratio within
//! [`DUTY_MARGIN`] of 0 or 1 (a pulse the counter may have dropped). With the set fixed, the final fit's loss is smooth where it
//! is: a parameter's change turns no kept sample's sign. The same idea as the dead-time
//! mask ([`crate::pmsm::model::mask`]), with the model's own current and a threshold from
//! its own residual instead of the sampled current and the dead-time pulse's bound.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{CriterionCorrection, Weighting};
use crate::model::GreyBoxModel;
use crate::pmsm::model::pwm::PmsmPwm;

/// The threshold in trimmed residual rms (see the module documentation).
pub(crate) const MARGIN_SCALES: f64 = 3.0;

/// The share of the largest residuals the rms leaves out.
pub(crate) const TRIMMED: f64 = 0.01;

/// A duty ratio's distance to 0 or 1 below which a period is masked \[1\], or 1.5 levels of
/// the counter (`--pwm-levels`) if that is more: a pulse this short the counter's
/// resolution or a driver's minimum pulse may drop, and the log cannot tell whether it did
/// (one such pulse is the dead time's `U_dc t_d / L` on the current, 0.25 A on the shared
/// 3 µs log, where a 4096-level counter rounds it away).
pub(crate) const DUTY_MARGIN: f64 = 1e-3;

/// A weighting that weights out the masked samples of the logs it was made for, and keeps
/// the `inner` rule's weights elsewhere (and on any other log).
#[derive(Debug)]
pub(crate) struct SignMask<'a> {
    inner: &'a dyn Weighting,
    /// Per log of the fit: its address (identity, not content) and which samples are masked.
    logs: Vec<(usize, Vec<bool>)>,
    /// The threshold \[A\].
    pub margin: f64,
    /// The criterion's compensation for the noise on the predictor's start, if any
    /// ([`super::pwm_noise`]).
    correction: Option<Box<dyn CriterionCorrection>>,
}

impl<'a> SignMask<'a> {
    /// The same mask with the criterion compensated by `correction`.
    pub(crate) fn compensated(&self, correction: Box<dyn CriterionCorrection>) -> SignMask<'a> {
        SignMask {
            inner: self.inner,
            logs: self.logs.clone(),
            margin: self.margin,
            correction: Some(correction),
        }
    }

    /// Whether `other` weights out the same samples of the same logs.
    pub(crate) fn same_samples(&self, other: &SignMask<'_>) -> bool {
        self.logs == other.logs
    }
}

impl Weighting for SignMask<'_> {
    fn name(&self) -> String {
        format!(
            "{} without the periods that pass a predicted phase current within {:.3e} A of zero",
            self.inner.name(),
            self.margin
        )
    }
    fn sample_weight(&self, e: &Experiment, k: usize) -> f64 {
        let id = std::ptr::from_ref(e) as usize;
        match self.logs.iter().find(|(a, _)| *a == id) {
            Some((_, masked)) if masked.get(k).copied().unwrap_or(false) => 0.0,
            _ => self.inner.sample_weight(e, k),
        }
    }
    fn output_weights(&self) -> Option<Vec<f64>> {
        self.inner.output_weights()
    }
    fn check(&self, e: &Experiment) -> Result<()> {
        self.inner.check(e)
    }
    fn criterion_correction(&self) -> Option<&dyn CriterionCorrection> {
        self.correction.as_deref()
    }
}

/// The sign mask of `experiments` for `model` at `theta` over the `inner` weighting, and a
/// note saying how many samples it weights out.
///
/// # Errors
/// Those of the model's `prepare` and [`PmsmPwm::sign_margins`]; [`Error::TooShort`] when a
/// log would keep fewer than [`crate::pmsm::log::signals::MIN_SAMPLES`] samples.
pub(crate) fn sign_mask<'a>(
    experiments: &[Experiment],
    model: &PmsmPwm,
    theta: &[f64],
    inner: &'a dyn Weighting,
) -> Result<(SignMask<'a>, String)> {
    scaled_sign_mask(experiments, model, theta, inner, MARGIN_SCALES)
}

/// [`sign_mask`] with the threshold `scales` × the trimmed rms instead of
/// [`MARGIN_SCALES`] × (a final fit stopped at a kink, [`super::pwm_fit`]).
///
/// # Errors
/// Those of [`sign_mask`].
pub(crate) fn scaled_sign_mask<'a>(
    experiments: &[Experiment],
    model: &PmsmPwm,
    theta: &[f64],
    inner: &'a dyn Weighting,
    scales: f64,
) -> Result<(SignMask<'a>, String)> {
    let mut margins = Vec::with_capacity(experiments.len());
    let mut squares = Vec::new();
    for e in experiments {
        let m = model.sign_margins(theta, &model.prepare(e)?)?;
        let counted = |k: usize| inner.sample_weight(e, k) > 0.0;
        squares.extend(m.iter().enumerate().filter(|(k, _)| counted(*k)).map(|(_, m)| m.residual.powi(2)));
        margins.push(m);
    }
    squares.sort_unstable_by(f64::total_cmp);
    let kept = &squares[..squares.len() - (TRIMMED * squares.len() as f64) as usize];
    let rms = (kept.iter().sum::<f64>() / kept.len().max(1) as f64).sqrt();
    let margin = scales * rms;
    let duty = model.inverter().levels.map_or(DUTY_MARGIN, |n| DUTY_MARGIN.max(1.5 / f64::from(n.max(1))));
    let mut logs = Vec::with_capacity(experiments.len());
    let (mut masked_total, mut total) = (0, 0);
    for (e, nearest) in experiments.iter().zip(margins) {
        let masked: Vec<bool> = nearest.iter().map(|m| m.current < margin || m.duty < duty).collect();
        let n_masked = masked.iter().filter(|m| **m).count();
        if e.len() - n_masked < crate::pmsm::log::signals::MIN_SAMPLES {
            return Err(Error::TooShort {
                name: e.name().to_string(),
                len: e.len() - n_masked,
                min: crate::pmsm::log::signals::MIN_SAMPLES,
            });
        }
        masked_total += n_masked;
        total += e.len();
        logs.push((std::ptr::from_ref(e) as usize, masked));
    }
    let note = format!(
        "PWM sign mask: {masked_total} of {total} samples weighted out, whose period passes a predicted phase \
         current within {margin:.3e} A of zero ({scales} × the one-step residual's rms {rms:.3e} A, its \
         largest {:.0} % left out) or a duty ratio within {duty:.1e} of 0 or 1",
        TRIMMED * 100.0
    );
    Ok((SignMask { inner, logs, margin, correction: None }, note))
}
