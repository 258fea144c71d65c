//! The dynamic fit from the logged terminal voltage checked against the steady-state
//! equations on the same logs (issue 43): two models of one motor, one of which holds the
//! voltage over each sample interval and one of which does not, must agree on R_s and K_e
//! within their intervals.
//!
//! Why: telemetry that keeps every 2nd row of a drive's log holds, in each new interval,
//! the mean voltage over its first half only. The dynamic model's held voltage is then
//! wrong, but neither point samples (the voltage-sampling check's trapezoid simulates such
//! logs worse than the held voltage) nor a mean the fit can see at its own estimate (a
//! quarter weight on the next sample, the hypothesis's own, simulates them worse there
//! too; only a refit with it fits better, 1.46–1.60 times). Every 2nd row of four
//! independent noise-free 5 kHz logs of short moves (2.5 kHz) was fitted with R_s 0.4–1.0 %
//! low at |z| 4.3–13.5 and K_e 0.06–0.16 % low at |z| 4.8–6.7, exit 0; the steady-state
//! equations, which take the samples as points and read `di/dt` by central differences,
//! put R_s within 0.02 % and K_e within 0.003 % on the same rows. Their difference is
//! 4.3–13.4 standard errors on R_s or 3.9–6.3 on K_e there, and at most 1.4 on the full
//! logs (shared and independent, noise-free and noisy).
//!
//! The check runs only where the dynamic fit's residuals fail the Ljung–Box test (a held
//! voltage that is wrong leaves its error in them; white residuals leave nothing the
//! steady-state equations could add) and no output is fitted to within the steady-state
//! equations' own accuracy (an NRMSE fit of `100 (1 − 1e-4)` % or better: a wrong hold
//! leaves its error in every current, 0.3–50 % of it on the logs above, and a fit that
//! close is one the steady-state equations cannot judge; noise-free logs at their own rate
//! fit one output to 99.993–99.9997 %, and their residuals, the data's rounding, are as
//! coloured as a wrong hold's). It reads each log's first [`AGREEMENT_SAMPLES`], and the
//! steady-state fit with its own checks (its consecutive parts, the truncation error) is
//! made only to confirm a disagreement of the bare equations: a steady-state fit whose own
//! parts disagree is no reference (gym-electric-motor's 8 kHz SPM log, whose voltage is
//! held in dq: the bare equations put R_s 0.22 % from the right dynamic fit at 4.8
//! standard errors, and their parts disagree at p 4e-143).

use crate::data::Experiment;
use crate::estimate::{FitResult, Warning};
use crate::pmsm::linear::steady_state_of;
use crate::pmsm::log::DqLogs;
use crate::pmsm::options::PmsmFitOptions;

use super::steady_checks::EQUATIONS_ACCURACY;

/// Samples of each log, from its start, the steady-state fit of the check reads: enough
/// for every 2nd row of a 5–10 kHz log of moves (17 000–36 000 rows) whole.
pub const AGREEMENT_SAMPLES: usize = 32_768;

/// Standard errors of the difference beyond which the two fits disagree on a parameter:
/// the two-sided normal quantile of a family level of 1e-3 over the two parameters compared
/// (Bonferroni), `Φ⁻¹(1 − 2.5e-4)`, the level of the other checks' untrusted verdicts
/// ([`crate::pmsm::checks::segments::FAMILY_LEVEL`]).
pub const AGREEMENT_Z: f64 = 3.48;

/// The parameters compared: those the steady-state equations tell best from any log of
/// moves (the inductances need `di/dt`, which the equations read at the log's rate).
const COMPARED: [&str; 2] = ["r_s", "k_e"];

/// After a dynamic fit `fit` of `experiments` from the terminal voltage with `options`:
/// the untrusted `steady_state_disagrees` warning when its residuals are coloured (any
/// output fails the Ljung–Box test at 1 %), no output is fitted to within
/// [`EQUATIONS_ACCURACY`], and the steady-state equations on the logs' first
/// [`AGREEMENT_SAMPLES`] (the same model kind, pole pairs, cable and control period) put
/// R_s or K_e more than [`AGREEMENT_Z`] standard errors of the difference away from it:
/// first the bare equations (their standard errors and their accuracy as a rectangular
/// bound, `/√3`, in quadrature), then, to confirm, the steady-state fit with its own
/// checks, which must be trusted (short of `imprecise`), with its reported standard
/// errors. The difference's variance is the sum of the two fits': they read the same data,
/// so the sum overstates it, and the check errs towards agreement. `None` when they agree,
/// when the check does not run, or when a steady-state fit fails (too few smooth samples:
/// it cannot tell).
pub(crate) fn warning(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    fit: &FitResult,
) -> Option<Warning> {
    let n = fit.fit.samples;
    let exact = fit.fit.fit_percent.iter().any(|f| *f >= 100.0 * (1.0 - EQUATIONS_ACCURACY));
    if exact || fit.fit.whiteness.iter().all(|w| w.is_white(n)) {
        return None;
    }
    let heads: Vec<Experiment> = experiments
        .iter()
        .map(|e| e.slice(0..e.len().min(AGREEMENT_SAMPLES)))
        .collect::<Result<_, _>>()
        .ok()?;
    let dq = DqLogs::try_new(&heads).ok()?;
    let steady = super::steady::steady_options(options);
    let est = steady_state_of(&dq, options.pole_pairs, options.model, &steady).ok()?;
    let bare = |name: &str| {
        let j = (0..est.names.len()).find(|&j| est.names[j] == name && est.experiment[j].is_none())?;
        let accuracy = EQUATIONS_ACCURACY / 3f64.sqrt() * est.theta[j].abs();
        Some((est.theta[j], est.std_error[j].hypot(accuracy)))
    };
    if apart(fit, &bare).is_empty() {
        return None;
    }
    // Confirmed by the steady-state fit with its own checks: one whose consecutive parts
    // disagree (or that is otherwise untrusted, short of `imprecise`) is no reference.
    let checked = PmsmFitOptions { force: true, ..options.clone() };
    let reference = super::steady::fit_from(&dq, &checked, None, Some(est)).ok()?;
    if reference.report.warnings.iter().any(|w| w.untrusted && w.code != "imprecise") {
        return None;
    }
    let apart = apart(fit, &|name: &str| reference.parameter(name).map(|p| (p.value, p.std_error)));
    if apart.is_empty() {
        return None;
    }
    Some(Warning::untrusted(
        "steady_state_disagrees",
        format!(
            "the steady-state equations on the same samples disagree with the dynamic model: {}. The dynamic model \
             holds the logged voltage over each sample interval; telemetry kept from a faster log (every 2nd row: \
             the mean over the first half of each interval) does not satisfy it, and its residuals are coloured. \
             Fit the steady-state equations (--model {}), which take the samples as points, or log the drive at \
             its own control rate",
            apart.join("; "),
            super::steady::flag(options.model)
        ),
    ))
}

/// The parameters of [`COMPARED`] on which the dynamic `fit` and the steady-state
/// `steady(name) = (estimate, standard error)` lie more than [`AGREEMENT_Z`] standard
/// errors of the difference apart, each described.
fn apart(fit: &FitResult, steady: &dyn Fn(&str) -> Option<(f64, f64)>) -> Vec<String> {
    COMPARED
        .iter()
        .filter_map(|name| {
            let p = fit.parameter(name).filter(|p| !p.fixed && p.experiment.is_none())?;
            let ((value, std_error), dynamic) = (steady(name)?, p.value);
            let z = (dynamic - value) / p.std_error.hypot(std_error);
            (z.is_finite() && z.abs() > AGREEMENT_Z).then(|| {
                format!(
                    "{name} {dynamic:.6e} against {value:.6e} ({:+.3} %, {z:+.1} standard errors of the difference)",
                    100.0 * (dynamic / value - 1.0)
                )
            })
        })
        .collect()
}
