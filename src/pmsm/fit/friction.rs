//! The mechanical fit's own checks ([`super::mechanics::fit_mechanics`]): what generic
//! gates cannot know about friction (issue 43): that it dissipates energy, that a viscous
//! and a Coulomb term are one to the data when the Coulomb speed lies above the logged
//! speeds, and that coloured residuals need the coloured covariance the few windows of a
//! mechanical fit may not allow.

use crate::estimate::{FitResult, Warning};
use crate::pmsm::model::mechanics::Axis;

/// Correlation of a viscous and a Coulomb friction estimate beyond which the data cannot
/// tell them apart.
pub(crate) const FRICTION_CORRELATION: f64 = 0.999;

/// Fit percentage from which the windows' residual is the integration's and the log's
/// rounding (a noise-free log): its colour is then no model error the intervals should carry.
pub(crate) const EXACT_FIT_PERCENT: f64 = 99.99;

/// The friction's own checks, untrusted (generic gates cannot know that friction dissipates
/// energy): `friction_confounded` when a viscous `b` and a Coulomb `t_c` of the same log
/// correlate beyond ±[`FRICTION_CORRELATION`] (the Coulomb term `tanh(ω/ω_c)` is then
/// nearly linear over the logged speeds, peak `peak` \[rad/s\], at `coulomb_speed`
/// \[rad/s\]; on a linear `axis` its `f_c`, speeds in m/s); `non_physical` when a friction's whole 95 % interval lies below 0;
/// `coloured_residuals` when the residuals fail the whiteness test but the intervals are
/// the white-noise ones (too few windows for batch means) and the fit is not exact
/// ([`EXACT_FIT_PERCENT`]).
pub(crate) fn warnings(result: &FitResult, peak: f64, coulomb_speed: f64, axis: Axis) -> Vec<Warning> {
    let mut out = Vec::new();
    let (names, unit) = axis.names();
    let coulomb = names[2].0;
    // Each viscous friction with the Coulomb friction of the same log (`b`, `t_c`, or
    // `b[LOG]`, `t_c[LOG]` per log), by the correlation's own labels: its rows are the free
    // parameters only.
    let labels = &result.correlation_names;
    let confounded: Vec<String> = labels
        .iter()
        .enumerate()
        .filter_map(|(a, l)| {
            let log = l.strip_prefix('b').filter(|s| s.is_empty() || s.starts_with('['))?;
            let c = labels.iter().position(|m| m.strip_prefix(coulomb) == Some(log))?;
            let r = result.correlation.get(a)?.get(c).copied()?;
            (r.abs() > FRICTION_CORRELATION).then(|| format!("{l} and {coulomb}{log} {r:+.5}"))
        })
        .collect();
    if !confounded.is_empty() {
        out.push(Warning::untrusted(
            "friction_confounded",
            format!(
                "the viscous and Coulomb friction are one term to the data (correlation {}): the logged speeds \
                 reach {peak:.4} {unit}, over which tanh(ω/ω_c) at ω_c = {coulomb_speed} {unit} is nearly linear in \
                 ω, so B and T_c trade against each other; a Coulomb speed well below the speeds the axis moves at \
                 separates them (--coulomb-speed {:.2e}, a twentieth of the peak)",
                confounded.join(", "),
                peak / 20.0
            ),
        ));
    }
    let negative: Vec<String> = result
        .parameters
        .iter()
        .filter(|p| (p.name == "b" || p.name == coulomb) && !p.fixed && p.ci95[1] < 0.0)
        .map(|p| format!("{} = {:.4e} {} (95 % interval up to {:.3e})", p.name, p.value, p.unit, p.ci95[1]))
        .collect();
    if !negative.is_empty() {
        out.push(Warning::untrusted(
            "non_physical",
            format!(
                "friction dissipates energy, yet {} is negative beyond its interval: check the sign of the torque \
                 model (K_t) and of the speed column, the Coulomb speed (--coulomb-speed), and whether a load the \
                 model lacks drives the axis (--gravity, --constant-load, a t_load column)",
                negative.join(", ")
            ),
        ));
    }
    let u = &result.uncertainty;
    let exact = result.fit.fit_percent.iter().all(|f| *f >= EXACT_FIT_PERCENT);
    let coloured = !exact && u.ljung_box.iter().any(|q| *q > u.ljung_box_critical);
    if coloured && u.method == crate::estimate::CovarianceMethod::White {
        out.push(Warning::untrusted(
            "coloured_residuals",
            format!(
                "the windows' residuals are not white (Ljung–Box {:.1} against {:.1}) but too few windows for batch \
                 means: the white-noise intervals are too narrow; a shorter --window or a longer log",
                u.ljung_box.iter().copied().fold(0.0, f64::max),
                u.ljung_box_critical
            ),
        ));
    }
    out
}
