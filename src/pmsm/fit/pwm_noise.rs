//! The measured current's noise on the PWM one-step predictor's start, compensated in the
//! criterion.
//!
//! The predictor restarts every period from the measured current `y[k] = x[k] + e[k]`, so
//! the residual of sample k + 1 holds `e[k+1] − Φ_k e[k]`, `Φ_k` the period's transition
//! ([`PmsmPwm::noise_terms`]). The criterion's expectation then carries
//! `c(θ) = ½ Σ_k w tr(Λ Φ_k Σ Φ_kᵀ)`, which depends on the resistances and inductances:
//! least squares lowers it by damping `Φ` (measured on the shared 3 µs log with 0.05 A per
//! phase and the inverter held at its truth: r_s +1.2 … +1.3 %, at 4 standard errors, where
//! this term predicts +1.3 %). Σ is read off the residuals' lag-1 covariance,
//! `E r[k+2] r[k+1]ᵀ = −Φ_{k+1} Σ`, which smooth model errors and the output's own white
//! noise do not enter, and the final fit subtracts `c(θ)` from its criterion
//! ([`crate::estimate::correction`]: bias-compensated least squares, Söderström,
//! *Automatica* 43 (2007) 939–958, section 5). Its standard errors are the larger of the
//! white and the batch-means ones ([`crate::estimate::correction`]).

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::{CriterionCorrection, FitResult, Weighting};
use crate::model::GreyBoxModel;
use crate::pmsm::model::pwm::{PmsmPwm, PwmInputs};
use nalgebra::{Matrix2, Vector2};

/// The share of the one-step residual's variance (`½ tr E r rᵀ`) below which the start's
/// noise `tr Σ` is taken as none and the criterion is not compensated: on a noise-free log
/// the printed digits give about 1e-3, with 0.05 A of noise per phase about 1.
pub const START_NOISE_SHARE: f64 = 0.1;

/// The compensation of the criterion: per experiment its prepared inputs and sample
/// weights (length N), the noise's covariance Σ \[A²\] and the output weights Λ.
#[derive(Debug)]
struct StartNoise {
    model: PmsmPwm,
    inputs: Vec<PwmInputs>,
    weights: Vec<Vec<f64>>,
    sigma: [f64; 4],
    lambda: [f64; 2],
}

impl CriterionCorrection for StartNoise {
    fn term(&self, experiment: usize, theta: &[f64]) -> Result<(f64, Vec<f64>)> {
        self.model.start_noise_share(
            theta,
            &self.inputs[experiment],
            self.sigma,
            self.lambda,
            &self.weights[experiment],
        )
    }
    fn value(&self, experiment: usize, theta: &[f64]) -> Result<f64> {
        self.model.start_noise_share_value(
            theta,
            &self.inputs[experiment],
            self.sigma,
            self.lambda,
            &self.weights[experiment],
        )
    }
}

/// The covariance Σ of the noise on the predictor's start \[A², row-major\] of `model` at
/// `theta` (model order) over the samples `weighting` counts, projected onto the positive
/// semi-definite matrices, and its share of the one-step residual (`tr Σ / ½ tr E r rᵀ`).
///
/// # Errors
/// Those of the model's `prepare` and [`PmsmPwm::noise_terms`].
fn start_noise(
    experiments: &[Experiment],
    model: &PmsmPwm,
    theta: &[f64],
    weighting: &dyn Weighting,
) -> Result<(Matrix2<f64>, f64)> {
    let (mut lag1, mut lag0) = (Matrix2::zeros(), Matrix2::zeros());
    let (mut n1, mut n0) = (0.0, 0.0);
    for e in experiments {
        let terms = model.noise_terms(theta, &model.prepare(e)?)?;
        let counted = |k: usize| weighting.sample_weight(e, k) > 0.0;
        for (k, (r, _)) in terms.iter().enumerate().filter(|(k, _)| counted(k + 1)) {
            let r1 = Vector2::new(r[0], r[1]);
            lag0 += r1 * r1.transpose();
            n0 += 1.0;
            let Some((r2, phi)) = terms.get(k + 1).filter(|_| counted(k + 2)) else { continue };
            if let Some(inv) = Matrix2::new(phi[0], phi[1], phi[2], phi[3]).try_inverse() {
                lag1 -= inv * Vector2::new(r2[0], r2[1]) * r1.transpose();
                n1 += 1.0;
            }
        }
    }
    if n1 < 1.0 || n0 < 1.0 {
        return Ok((Matrix2::zeros(), 0.0));
    }
    let lag1 = lag1 / n1;
    let eig = ((lag1 + lag1.transpose()) * 0.5).symmetric_eigen();
    let sigma = eig.eigenvectors
        * Matrix2::from_diagonal(&eig.eigenvalues.map(|v| v.max(0.0)))
        * eig.eigenvectors.transpose();
    let residual = 0.5 * (lag0 / n0).trace();
    Ok((sigma, if residual > 0.0 { sigma.trace() / residual } else { 0.0 }))
}

/// The start's noise of [`compensation`]: the criterion's compensation (`None` where the
/// noise is below [`START_NOISE_SHARE`] of the residual), a note, and the noise's rms per
/// axis `√(tr Σ / 2)` \[A\].
pub(crate) struct StartCompensation {
    pub correction: Option<Box<dyn CriterionCorrection>>,
    pub note: String,
    pub rms: f64,
}

/// The estimate of `fit` as `model`'s θ (model order, length n_θ; NaN for a parameter the
/// fit does not report).
fn estimate_theta(model: &PmsmPwm, fit: &FitResult) -> Vec<f64> {
    model.parameters().iter().map(|p| fit.parameter(&p.name).map_or(f64::NAN, |e| e.value)).collect()
}

/// The compensated criterion `J = V − Σ_e c_e(θ̂)` of a fit `fit` of `model` (its loss `V`
/// on the weighting that carries `correction`; θ̂ in model order, the same for each of the
/// `experiments`), in the units of the loss.
///
/// # Errors
/// Those of the correction's value at θ̂.
pub(crate) fn compensated_loss(
    fit: &FitResult,
    model: &PmsmPwm,
    correction: &dyn CriterionCorrection,
    experiments: usize,
) -> Result<f64> {
    let theta = estimate_theta(model, fit);
    let mut c = 0.0;
    for e in 0..experiments {
        c += correction.value(e, &theta)?;
    }
    Ok(fit.fit.loss - c)
}

/// The compensation of `model`'s one-step criterion at the estimate `fit` over the samples
/// `weighting` counts ([`StartCompensation`]).
///
/// # Errors
/// Those of the model's `prepare`, [`PmsmPwm::noise_terms`] and the weighting's weights.
pub(crate) fn compensation(
    experiments: &[Experiment],
    model: &PmsmPwm,
    fit: &FitResult,
    weighting: &dyn Weighting,
) -> Result<StartCompensation> {
    let theta = estimate_theta(model, fit);
    let (sigma, share) = start_noise(experiments, model, &theta, weighting)?;
    let text = format!(
        "the measured current's noise on the PWM predictor's start: Σ = [{:.3e} {:.3e}; {:.3e} {:.3e}] A², {:.3} \
         of the one-step residual's variance (lag-1 covariance)",
        sigma[(0, 0)],
        sigma[(0, 1)],
        sigma[(1, 0)],
        sigma[(1, 1)],
        share
    );
    let rms = (0.5 * (sigma[(0, 0)] + sigma[(1, 1)])).max(0.0).sqrt();
    if share < START_NOISE_SHARE {
        let note = format!("{text}: below {START_NOISE_SHARE}, the criterion is not compensated");
        return Ok(StartCompensation { correction: None, note, rms });
    }
    let lambda = weighting.output_weights().map_or([1.0, 1.0], |l| [l[0], l.get(1).copied().unwrap_or(1.0)]);
    let inputs = experiments.iter().map(|e| model.prepare(e)).collect::<Result<Vec<_>>>()?;
    let weights = experiments.iter().map(|e| weighting.weights(e)).collect::<Result<Vec<_>>>()?;
    let correction = StartNoise {
        model: model.clone(),
        inputs,
        weights,
        sigma: [sigma[(0, 0)], sigma[(0, 1)], sigma[(1, 0)], sigma[(1, 1)]],
        lambda,
    };
    Ok(StartCompensation {
        correction: Some(Box::new(correction)),
        note: format!(
            "{text}: the final fit subtracts its share from the criterion (bias-compensated least squares), and \
             each standard error is the larger of the white and the batch-means one"
        ),
        rms,
    })
}
