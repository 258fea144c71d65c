//! The noise check of a masked fit: how far the currents' own noise moves its estimate.
//!
//! Why: the dead-time mask weights out single periods, so the masked fit predicts one step
//! ahead from the measured current `i[k]` (an equation-error fit). Noise on that regressor
//! biases it (errors in variables; Söderström, *Automatica* 43 (2007) 939–958, 2): the step's
//! pole `a = 1 − h R_s / L` is pulled towards zero by about `a σ² / var(i)`, and `R_s` comes
//! from `1 − a`, so the bias is large: on a drive-simulator log with 0.05 A of current noise
//! (exp6, `v_dt` 6 V) `r_s` came out 12 % high at 5 standard errors with exit 0. The bias is
//! proportional to the noise variance σ² for small σ, so adding noise of the same level once
//! more moves the estimate by about the bias (the first step of SIMEX: Cook & Stefanski,
//! *J. Am. Stat. Assoc.* 89 (1994) 1314–1328). σ² is read off the one-step residuals: for
//! white measurement noise `n` the residual `n[k+1] − a n[k]` has the lag-1 autocovariance
//! `−a σ²` (taken with `a = 1`: σ² a little low).

use crate::data::{Channel, Experiment};
use crate::estimate::{FitResult, Warning};
use crate::pmsm::log::signals::channel::{I_D, I_Q};
use crate::pmsm::options::{PmsmFitOptions, RefitReport};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

/// Refits with fresh noise added, averaged: one refit's shift holds a random part of about
/// a standard error; the mean of four, about half of one.
pub const REPLICATES: u64 = 4;

/// Shift, in standard errors, beyond which the bias makes the fit untrusted.
pub const BIAS_Z: f64 = 2.0;

/// After a masked fit `fit` of `experiments`: an untrusted `noise_bias` warning when adding
/// current noise of the level its residuals show moves an estimate (the mean over
/// [`REPLICATES`] refits with `options`) by more than [`BIAS_Z`] standard errors. `None`
/// when the residuals show no measurement noise (a lag-1 autocorrelation ≥ 0) or a refit
/// fails.
pub(crate) fn warning(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    fit: &FitResult,
    refit: RefitReport<'_>,
) -> Option<Warning> {
    let (s_d, s_q) = (sigma(fit, I_D), sigma(fit, I_Q));
    if s_d == 0.0 && s_q == 0.0 {
        return None;
    }
    let biased: Vec<String> = simex_shifts(experiments, &[(I_D, s_d), (I_Q, s_q)], options, fit, refit)?
        .iter()
        .filter(|s| s.z.abs() > BIAS_Z)
        .map(Shift::describe)
        .collect();
    if biased.is_empty() {
        return None;
    }
    Some(Warning::untrusted(
        "noise_bias",
        format!(
            "the masked fit predicts each period from the measured current, whose noise biases it (errors in \
             variables): with noise of the level its residuals show ({s_d:.3e} A on {I_D}, {s_q:.3e} A on {I_Q}) \
             added once more, {} — the estimates are off by about as much. Fit the measured terminal voltage if the \
             drive logs it (--voltage actual), or log the currents with less noise",
            biased.join(", ")
        ),
    ))
}

/// How far one parameter moved when noise was added once more ([`simex_shifts`]).
pub(crate) struct Shift {
    /// The parameter.
    pub name: String,
    /// Its estimate \[its unit\].
    pub value: f64,
    /// The refits' mean shift from it \[its unit\].
    pub shift: f64,
    /// The shift in the fit's standard errors.
    pub z: f64,
}

impl Shift {
    /// `name by +x.xx % (+z.z standard errors)`.
    pub fn describe(&self) -> String {
        format!("{} by {:+.2} % ({:+.1} standard errors)", self.name, 100.0 * self.shift / self.value, self.z)
    }
}

/// The first step of SIMEX (Cook & Stefanski 1994): the mean shift of every free, shared
/// parameter of `fit` over [`REPLICATES`] refits of `experiments` with `options`, each with
/// fresh white Gaussian noise of the standard deviations `noise` (`(channel, σ)`) added. For
/// noise whose bias grows with its variance, the shift is about the bias itself. `None` when
/// a refit fails or a log lacks a channel.
pub(crate) fn simex_shifts(
    experiments: &[Experiment],
    noise: &[(&str, f64)],
    options: &PmsmFitOptions,
    fit: &FitResult,
    refit: RefitReport<'_>,
) -> Option<Vec<Shift>> {
    let fits: Option<Vec<FitResult>> = (0..REPLICATES)
        .into_par_iter()
        .map(|seed| {
            let noisier = with_noise(experiments, noise, seed)?;
            refit(&noisier, options)
        })
        .collect();
    let fits = fits?;
    Some(
        fit.parameters
            .iter()
            .filter(|p| !p.fixed && p.experiment.is_none() && p.std_error > 0.0 && p.std_error.is_finite())
            .filter_map(|p| {
                let moved: Vec<f64> =
                    fits.iter().filter_map(|f| f.parameter(&p.name)).map(|q| q.value).collect();
                (moved.len() == fits.len()).then(|| {
                    let shift = moved.iter().sum::<f64>() / moved.len() as f64 - p.value;
                    Shift { name: p.name.clone(), value: p.value, shift, z: shift / p.std_error }
                })
            })
            .collect(),
    )
}

/// The measurement noise σ \[A\] of output `name` read off a one-step fit's residuals,
/// `√(−ρ₁) × rms` (0 when the lag-1 autocorrelation ρ₁ is not negative or not reported).
fn sigma(fit: &FitResult, name: &str) -> f64 {
    let stats = &fit.fit;
    let read = || {
        let i = stats.outputs.iter().position(|o| o == name)?;
        let rho_1 = *stats.whiteness.get(i)?.autocorrelation.first()?;
        let rms = *stats.rms_residual.get(i)?;
        Some((-rho_1 * rms * rms).max(0.0).sqrt()).filter(|s| s.is_finite())
    };
    read().unwrap_or(0.0)
}

/// The logs with white Gaussian noise of the standard deviations `noise` (`(channel, σ)`, σ in
/// the channel's unit) added to those channels (the same for a given `seed`). `None` when a
/// log lacks one.
fn with_noise(experiments: &[Experiment], noise: &[(&str, f64)], seed: u64) -> Option<Vec<Experiment>> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0000 + seed);
    experiments
        .iter()
        .map(|e| {
            let mut e = e.clone();
            for &(name, s) in noise {
                let normal = Normal::new(0.0, s).ok()?;
                let c = e.get(name)?;
                let values: Vec<f64> = c.values.iter().map(|v| v + normal.sample(&mut rng)).collect();
                let unit = c.unit.clone();
                e = e.with_channel(Channel::new(name, unit, values)).ok()?;
            }
            Some(e)
        })
        .collect()
}
