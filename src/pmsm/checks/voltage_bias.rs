//! The voltage-noise check of a fit from the measured terminal voltage: how far the logged
//! voltage's own noise moves the output-error estimate.
//!
//! Why: output error drives the model with the logged voltage, so noise on it enters the
//! simulated current and correlates with the residual (errors in variables; Söderström,
//! *Automatica* 43 (2007) 939–958). The batch-means covariance makes the interval as wide as
//! the coloured residual asks, but not wide enough to hold the bias: with 1 V of voltage and
//! 0.03 A of current noise on an independent 72 000-sample log, l_s came out 2 standard
//! errors high on average and its 95 % interval held the truth in 51 % of 40 seeds, r_s in
//! 80 %, all with exit 0. The bias grows with the noise's variance, so adding noise of the
//! level the log shows once more moves the estimate by about the bias (SIMEX's first step:
//! Cook & Stefanski, *J. Am. Stat. Assoc.* 89 (1994) 1314–1328). The level is read off the
//! inverse model's voltage errors ([`super::noise::voltage_noise`]), which tell the voltage's
//! white noise from the currents' noise and the model's slow error.

use crate::estimate::{CovarianceMethod, FitResult, Warning};
use crate::pmsm::checks::noise::{NEGLIGIBLE_VOLTAGE_NOISE, voltage_noise};
use crate::pmsm::checks::noise_bias::{Shift, simex_shifts};
use crate::pmsm::log::DqLogs;
use crate::pmsm::log::signals::channel::{U_D, U_Q};
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::options::{PmsmFitOptions, RefitReport};

/// Shift, in standard errors, beyond which the voltage noise's bias makes the output-error
/// fit untrusted. Lower than the masked fit's [`BIAS_Z`](super::noise_bias::BIAS_Z): a bias of
/// one standard error already takes the 95 % interval's coverage to 83 %, and the method
/// this check names (instrumental variables) is unbiased whatever the noise, so a false
/// alarm costs variance, not honesty. The mean of four refits has a random part of about
/// half a standard error.
pub const VOLTAGE_BIAS_Z: f64 = 1.0;

/// Share of the inverse model's voltage-error RMS value below which the voltage noise read
/// off them is not taken as such (its variance under 1 % of theirs): on an exact log the
/// estimate's residue is the model's slow error, whose refits would move an exact fit by
/// many of its tiny standard errors; on a log with current noise the voltage noise is then
/// small beside it (0.02 V of voltage noise beside 0.05 A of current noise on the shared
/// motulator log: a share of about 0.008).
pub const VOLTAGE_NOISE_SHARE: f64 = 0.1;

/// After an output-error fit (its report `fit`, its `setup`'s pole pairs and hold) of
/// surface- or interior-magnet motors' logs `dq` from their terminal voltage: an
/// untrusted `voltage_noise_bias` warning when the logged voltage carries noise that is not
/// negligible (over [`NEGLIGIBLE_VOLTAGE_NOISE`] of its RMS value and
/// [`VOLTAGE_NOISE_SHARE`] of the voltage errors') and adding noise of that
/// level once more moves an estimate (the mean of the refits with `parts`, the fit's own
/// hold and start) by more than [`VOLTAGE_BIAS_Z`] standard errors. `None` for white
/// residuals (the white-noise covariance: no coloured noise to read), for a log the inverse
/// model cannot read, or when a refit fails.
pub(crate) fn warning(
    dq: &DqLogs<'_>,
    options: &PmsmFitOptions,
    fit: &FitResult,
    setup: PmsmSetup,
    parts: &PmsmFitOptions,
    refit: RefitReport<'_>,
) -> Option<Warning> {
    if fit.uncertainty.method != CovarianceMethod::BatchMeans {
        return None;
    }
    // Each model's own voltage errors: an IPM's read with a mean inductance would leave the
    // saliency's error, which follows the currents' steps and is no smooth error the noise
    // estimate cancels (it took the noise-free gym-electric-motor IPM log for a noisy one).
    // The model's parameters in its order, with the whole series resistance.
    let theta = options.series_theta(fit)?;
    let (sigma, errors, rms) = voltage_noise(dq.views(), setup, &theta)?;
    if !(sigma > NEGLIGIBLE_VOLTAGE_NOISE * rms && sigma > VOLTAGE_NOISE_SHARE * errors) {
        return None;
    }
    let shifts = simex_shifts(dq.experiments(), &[(U_D, sigma), (U_Q, sigma)], parts, fit, refit)?;
    let biased: Vec<String> =
        shifts.iter().filter(|s| s.z.abs() > VOLTAGE_BIAS_Z).map(Shift::describe).collect();
    (!biased.is_empty()).then(|| {
        Warning::untrusted(
            "voltage_noise_bias",
            format!(
                "the logged voltage carries noise (σ ≈ {sigma:.3e} V per axis, read off the voltage equations' \
                 errors), which output error filters into its residuals and which biases it (errors in variables): \
                 with that noise added once more, {} — the estimates are off by about as much. --method iv \
                 (instrumental variables on the inverse model, which the default --method auto takes) is not \
                 biased by it",
                biased.join(", ")
            ),
        )
    })
}
