//! Whether a log too slow for the dynamic model is a fast log whose time column is in
//! other units than the reader took (milliseconds read as seconds): such a log is named as
//! such, not fitted by the steady-state equations (issue 32).
//!
//! Two signs, either suffices:
//! - **the angle** (when `theta_m` is logged): its advance per sample is `10⁻³` (or `10⁻⁶`)
//!   of what the speed says at the sample time read ([`super::detect`]'s speed sums);
//! - **the currents' dynamics**: in the regression of the voltage equations with the
//!   derivative columns free ([`super::scan::scan_gram`]), the inductance seen through
//!   `di/dt` is `10³` (or `10⁶`) times the one seen through the rotation terms `ω_e L i`,
//!   the derivative being taken over a sample time that many times too long. A genuinely
//!   slow log's currents settle within a sample: its `di/dt` column carries no such
//!   consistent inductance.

use super::detect::speed_sums;
use super::scan::{BASE, scan_gram};
use crate::pmsm::log::longest_h;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::VoltageInput;

/// The factors of a time column read in seconds while it is in ms or µs, with their unit.
const FACTORS: [(f64, &str); 2] = [(1e3, "milliseconds"), (1e6, "microseconds")];

/// The angle's ratio counts as a factor when within this factor of it (the angle and the
/// speed agree to a few % in any log).
const ANGLE_WITHIN: f64 = 1.5;

/// The derivative's ratio counts as a factor when within this factor of it: the scan's
/// low-pass and the currents' noise bias the inductance through `di/dt` low (measured 0.39
/// to 0.93 of the factor on 10 kHz drive-simulator logs read in ms), while genuinely slow
/// logs give ratios of either sign below 100 in size (−1.8 at 100 Hz, −86 at 2 Hz).
const DERIVATIVE_WITHIN: f64 = 10.0;

/// Fewest samples (all logs) for the derivative's sign: a fast log read in ms holds
/// thousands, while a few dozen rows of slow telemetry (every 2000th row of a drive
/// cycle: 36) give a ratio of any size from their few steady-looking intervals (172 on
/// one, which a 10 kHz log read in ms would give as well).
const DERIVATIVE_MIN_SAMPLES: usize = 500;

/// The unit a positive ratio `r` (seen / expected) points to within `within`, if any.
fn unit_of(r: f64, within: f64) -> Option<(f64, &'static str)> {
    FACTORS.into_iter().find(|(f, _)| r.is_finite() && r > 0.0 && (r / f).ln().abs() < within.ln())
}

/// `dθ_m/dt` over `w_m` on the logs that have the angle (`None` without it).
fn angle_ratio(views: &[DqView<'_>]) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for v in views {
        let Some(th) = v.theta_m() else { continue };
        (num, den) = speed_sums((num, den), th, v.w_m(), v.h());
    }
    (den > 0.0).then(|| num / den)
}

/// The inductance through `di/dt` over the one through `ω_e L i` in the free regression of
/// the voltage equations at `n_p` pole pairs (`None` when it cannot be formed).
fn derivative_ratio(views: &[DqView<'_>], n_p: u32) -> Option<f64> {
    let g = scan_gram(views, VoltageInput::Terminal).ok()?;
    let a = g.view((0, 0), (BASE, BASE)).into_owned();
    let b = g.view((0, BASE), (BASE, 1)).into_owned();
    let theta = a.cholesky()?.solve(&b);
    // Base columns: i, di_d/dt, ω_m i_d, −ω_m i_q, di_q/dt, √(2/3) ω_m.
    let l_deriv = 0.5 * (theta[1] + theta[4]);
    let l_rot = 0.5 * (theta[2] + theta[3]) / f64::from(n_p);
    Some(l_deriv / l_rot)
}

/// Why the logs `views` look like a fast log with its time column in ms or µs read as s, or
/// `None` (module documentation).
pub(crate) fn time_unit_mistake(views: &[DqView<'_>], n_p: u32) -> Option<String> {
    let h = longest_h(views);
    let fix = |f: f64, unit: &str| {
        let flag = if unit == "milliseconds" { "ms" } else { "us" };
        format!("the time column is in {unit}? (--time-unit {flag} gives h = {:.4e} s)", h / f)
    };
    if let Some(r) = angle_ratio(views)
        && let Some((f, unit)) = unit_of(1.0 / r, ANGLE_WITHIN)
    {
        return Some(format!(
            "the angle advances {:.4e} times what the speed says at h = {h:.4e} s: {}",
            r,
            fix(f, unit)
        ));
    }
    if views.iter().map(DqView::len).sum::<usize>() < DERIVATIVE_MIN_SAMPLES {
        return None;
    }
    let q = derivative_ratio(views, n_p)?;
    unit_of(q, DERIVATIVE_WITHIN).map(|(f, unit)| {
        format!(
            "the currents move between samples as an inductance {q:.3e} times the one the rotation terms show \
             (their derivative is taken over a sample time that many times too long): {}",
            fix(f, unit)
        )
    })
}
