//! The automatic dead-time mask ([`DeadTimeMask::Auto`]): the unmasked fit, then masked
//! fits whose current threshold `4 h V_dt / L` comes from the latest fit.

use crate::error::{Error, Result};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::log::{DqLogs, longest_h, peak_current};
use crate::pmsm::model::inverter::InverterModel;
use crate::pmsm::model::mask::{AUTO_ITERATIONS, DeadTimeMask};
use crate::pmsm::options::{PmsmFitOptions, RefitReport};

/// Threshold relative to the largest current magnitude of the logs when a fit gives no
/// positive `4 h V_dt / L` (e.g. `v_dt` at its bound 0 before the mask).
pub const FALLBACK_RELATIVE_THRESHOLD: f64 = 0.05;

/// `4 h V_dt / L` \[A\] from a fit (`h` the longest sample time of the logs, `L` the smallest
/// inductance estimate), or `None` when that is not positive and finite.
fn auto_threshold(views: &[DqView<'_>], fit: &PmsmFit) -> Option<f64> {
    let h = longest_h(views);
    let l = crate::pmsm::model::kind::smallest_inductance(fit);
    let v_dt = fit.parameter("v_dt").map_or(f64::NAN, |p| p.value);
    Some(4.0 * h * v_dt / l).filter(|t| t.is_finite() && *t > 0.0)
}

/// [`FALLBACK_RELATIVE_THRESHOLD`] × the largest `|i_dq|` of the logs \[A\].
fn fallback_threshold(views: &[DqView<'_>]) -> Result<f64> {
    let peak = peak_current(views);
    Some(FALLBACK_RELATIVE_THRESHOLD * peak).filter(|t| t.is_finite() && *t > 0.0).ok_or_else(|| {
        Error::Numerical {
            context: "dead-time mask".into(),
            reason: "no threshold: the currents are all zero (give the threshold in amperes)".into(),
        }
    })
}

/// [`crate::pmsm::fit_pmsm`] with [`DeadTimeMask::Auto`]: the unmasked fit, then the threshold
/// `4 h V_dt / L` from the latest fit, twice; the report records the threshold used.
///
/// When a fit gives no positive `4 h V_dt / L` (its `v_dt` at 0), the threshold is
/// [`FALLBACK_RELATIVE_THRESHOLD`] of the peak current for that step.
///
/// # Errors
/// Those of [`crate::pmsm::fit_pmsm`]; [`Error::Numerical`] when the currents are all zero.
pub(super) fn fit(dq: &DqLogs<'_>, options: &PmsmFitOptions, refit: RefitReport<'_>) -> Result<PmsmFit> {
    let inverter = options.inverter.unwrap_or_default();
    let with_mask = |mask: Option<DeadTimeMask>, start: Option<Vec<f64>>| PmsmFitOptions {
        inverter: Some(InverterModel { mask, ..inverter }),
        start: start.or_else(|| options.start.clone()),
        ..options.clone()
    };
    // The inner fits skip the setup checks; the last one runs them as `options` says.
    let mut fit =
        super::base::fit(dq, &PmsmFitOptions { skip_setup_checks: true, ..with_mask(None, None) }, refit)?;
    let mut trail = Vec::new();
    for step in 0..AUTO_ITERATIONS {
        let threshold = match auto_threshold(dq.views(), &fit) {
            Some(t) => t,
            None => {
                let t = fallback_threshold(dq.views())?;
                trail.push(format!(
                    "(v_dt {:.3e} V: {:.0} % of the peak current)",
                    fit.parameter("v_dt").map_or(f64::NAN, |p| p.value),
                    100.0 * FALLBACK_RELATIVE_THRESHOLD
                ));
                t
            }
        };
        trail.push(format!("{threshold:.4}"));
        let start = fit.inverter_start(options.model);
        let last = step + 1 == AUTO_ITERATIONS;
        let o = with_mask(Some(DeadTimeMask::Current(threshold)), start);
        fit = super::base::fit(
            dq,
            &PmsmFitOptions { skip_setup_checks: !last || options.skip_setup_checks, ..o },
            refit,
        )?;
    }
    let mut pmsm_notes = fit.pmsm_notes.clone();
    pmsm_notes.push(format!(
        "dead-time mask threshold 4 h v_dt / L by fixed-point iteration from the unmasked fit: {} A",
        trail.join(" → ")
    ));
    Ok(PmsmFit { pmsm_notes, ..fit })
}
