//! The segment check of a fit whose voltage is modelled (the controller's reference, the
//! inverter model): the logs cut into consecutive quarters, each fitted alone, and Cochran's
//! Q test of whether the quarters agree within their intervals (`estimate::consistency`).
//!
//! Why: the measured terminal voltage is the motor model's input as it was; the reference
//! voltage reaches the motor through a delay, a modulator's angle advance from the
//! controller's speed estimate and an inverter, each modelled, and each model can be wrong
//! in a way no interval shows (an interval describes the noise around the estimate, not the
//! model's error). Measured on the development logs: from the reference with the defaults
//! (speed estimate not modelled), `l_s` +0.29 % at |z| 8.7 with exit 0; from a carrier-PWM log
//! with the inverter model and the dead-time mask, `r_s` up to 2.8 % and `l_d` 1.1 % off at
//! |z| up to 6.5. Such errors depend on the operating point (acceleration, speed, current
//! level, the share of periods near a current zero), which changes along a drive log; so the
//! quarters' estimates scatter far beyond their intervals (Q with p ≤ 4e-5 on all of these),
//! while on logs the model describes (the drive simulator's dead-time logs; the reference
//! with the controller's speed estimate modelled, `--speed-pll`) they agree (p ≥ 0.03).

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::{FitResult, Warning};
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::options::{PmsmFitOptions, RefitReport};
use rayon::prelude::*;

/// Consecutive parts each log is cut into.
pub const SEGMENTS: usize = 4;

/// Fewest samples a part must hold for the check to run (a part this short cannot
/// identify the parameters well enough to tell model error from noise).
pub const MIN_SEGMENT_SAMPLES: usize = 2000;

/// Family-wise level of the test: each parameter's Q is tested at this level divided by
/// the number of parameters tested (Bonferroni). Small, because the check makes a fit
/// untrusted and the batch-means standard errors of a part are themselves estimates.
pub const FAMILY_LEVEL: f64 = 1e-3;

/// Accuracy of an exact fit (relative): the parts' standard errors are taken at least this
/// large, and a spread below it is agreement whatever Q says (a noise-free log's parts
/// differ by rounding, and their standard errors are as small).
pub const EXACT_SPREAD: f64 = 1e-5;

/// After a fit from the reference voltage or with the inverter model: an untrusted
/// `segments_disagree` warning when the
/// fits of the logs' [`SEGMENTS`] consecutive parts (with `options`: the fit's own hold,
/// mask and estimate as the start) disagree beyond their intervals. `None` when they agree,
/// when a part would be shorter than [`MIN_SEGMENT_SAMPLES`], or when fewer than two parts
/// can be fitted.
pub(crate) fn warning(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    refit: RefitReport<'_>,
) -> Option<Warning> {
    let parts = split(experiments).ok()?;
    let fits: Vec<_> = parts.par_iter().filter_map(|logs| refit(logs, options)).collect();
    let detail = disagreement(&fits, EXACT_SPREAD)?;
    let advice = match options.input {
        VoltageInput::Reference { speed_pll: None, .. }
            if options.inverter.is_none() && options.pwm.is_none() =>
        {
            "model the controller's speed estimate behind the modulator's angle advance (--speed-pll estimate, \
             which needs theta_m), or fit the measured terminal voltage if the drive logs it (--voltage actual)"
        }
        _ if options.pwm.is_some() => {
            "fit the measured terminal voltage if the drive logs it (--voltage actual), or check the PWM settings \
             (--u-dc, --pwm-update, --pwm-levels, --leg-state-width; docs/options.md)"
        }
        _ if options.inverter.is_some() => {
            "fit the measured terminal voltage if the drive logs it (--voltage actual), or compare \
             --dead-time-width estimate"
        }
        _ => "fit the measured terminal voltage if the drive logs it (--voltage actual)",
    };
    Some(Warning::untrusted(
        "segments_disagree",
        format!(
            "fitted alone, the {} consecutive parts of the log disagree beyond their intervals: {}. The voltage the \
             model applies (the reference's delay and angle advance, the inverter) misses something that changes \
             along the log, so the estimates carry a model error the intervals do not show; {advice}",
            fits.len(),
            detail
        ),
    ))
}

/// The parameters on which the fits of consecutive parts `fits` disagree beyond their
/// intervals at [`FAMILY_LEVEL`] ([`crate::estimate::consistency::disagreement`]), `floor`
/// the accuracy of an exact fit ([`EXACT_SPREAD`] for the exact sampled-data models).
pub(crate) fn disagreement(fits: &[FitResult], floor: f64) -> Option<String> {
    crate::estimate::consistency::disagreement(fits, floor, FAMILY_LEVEL)
}

/// The logs cut into [`SEGMENTS`] consecutive parts: part k holds the k-th part of every
/// log, named `LOG@k`.
///
/// # Errors
/// [`crate::Error::TooShort`] when a part would hold fewer than [`MIN_SEGMENT_SAMPLES`].
fn split(experiments: &[Experiment]) -> Result<Vec<Vec<Experiment>>> {
    split_at_least(experiments, MIN_SEGMENT_SAMPLES)
}

/// The logs cut into [`SEGMENTS`] consecutive parts of at least `min` samples each
/// ([`crate::estimate::consistency::consecutive_parts`]).
///
/// # Errors
/// [`crate::Error::TooShort`] when a part would hold fewer than `min`.
pub(crate) fn split_at_least(experiments: &[Experiment], min: usize) -> Result<Vec<Vec<Experiment>>> {
    crate::estimate::consistency::consecutive_parts(experiments, SEGMENTS, min)
}
