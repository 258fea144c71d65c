//! The steady-state fit checked against its own data (issue 43): the same equations
//! fitted on consecutive parts of the logs must agree within their intervals (Cochran's Q,
//! [`crate::pmsm::checks::segments::disagreement`]), and an SPM fit must not hide a
//! salient machine (the IPM equations on the same samples with `L_d`, `L_q` apart).
//!
//! Why: the steady-state equations hold only where the samples are smooth and the model is
//! right; a drive cycle's telemetry has short plateaus, and the equations' error where they
//! do not hold is a model error no interval shows. On an IPM log the SPM equations put the
//! saliency into R_s and K_e (every 2000th row of a 5 kHz IPM log of moves: K_e +4.3 % at
//! |z| 4.5, exit 0, before this check).

use crate::data::Experiment;
use crate::estimate::{FitResult, Warning};
use crate::pmsm::checks::detect::SALIENCY;
use crate::pmsm::checks::segments::{disagreement, split_at_least};
use crate::pmsm::linear::{PERIOD_TERM, SteadyEstimate, SteadyOptions, steady_state, steady_state_of};
use crate::pmsm::log::DqLogs;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::options::PmsmFitOptions;

/// Fewest samples of a part for the segment check of the steady-state fit (its equations
/// are linear and cheap; a part must still hold enough smooth samples to tell model
/// error from noise).
pub const MIN_PART_SAMPLES: usize = 200;

/// Accuracy of the steady-state equations on an exact log (relative): central differences
/// and the first-order period term leave about 3e-5 (R_s, L, K_e on every 40th–160th row
/// of the noise-free development logs), so parts closer than this agree.
pub const EQUATIONS_ACCURACY: f64 = 1e-4;

/// How many standard errors of `L_d − L_q` make an SPM log salient (with the inductances
/// more than [`SALIENCY`] apart).
pub const SALIENT_Z: f64 = 4.0;

/// The untrusted warnings of the steady-state fit `est` of the logs `dq`: the parts
/// disagree (`segments_disagree`), or the machine is salient under an SPM fit (`salient`).
/// `report` turns a part's estimate into a fit report.
pub(crate) fn warnings(
    dq: &DqLogs<'_>,
    options: &PmsmFitOptions,
    steady: &SteadyOptions,
    est: &SteadyEstimate,
    report: &dyn Fn(&SteadyEstimate, &[Experiment]) -> FitResult,
) -> Vec<Warning> {
    let mut out = Vec::new();
    if let Ok(parts) = split_at_least(dq.experiments(), MIN_PART_SAMPLES) {
        // The control period is the drive's, the same along the log: the parts hold the
        // whole fit's estimate (a part's speeds may not separate it from K_e).
        let h_c = est.value(PERIOD_TERM).filter(|c| *c > 0.0).map(f64::sqrt);
        let steady = &SteadyOptions { control_period: h_c.or(steady.control_period), ..steady.clone() };
        let fits: Vec<FitResult> = parts
            .iter()
            .filter_map(|logs| {
                steady_state(logs, options.pole_pairs, est.kind, steady).ok().map(|e| report(&e, logs))
            })
            .collect();
        if let Some(detail) = disagreement(&fits, EQUATIONS_ACCURACY) {
            out.push(Warning::untrusted(
                "segments_disagree",
                format!(
                    "fitted alone, the {} consecutive parts of the log disagree beyond their intervals: {detail}. \
                     The steady-state equations miss something that changes along the log (samples that are not \
                     steady, a drifting parameter, saturation), so the estimates carry a model error the \
                     intervals do not show; fit the fast log with the dynamic model if there is one, or give \
                     --control-period",
                    fits.len()
                ),
            ));
        }
    }
    if est.kind == MotorKind::Spm {
        out.extend(salient(dq, options, steady));
    }
    out
}

/// `salient` when the IPM equations on the same logs put `L_d` and `L_q` more than
/// [`SALIENCY`] and [`SALIENT_Z`] standard errors apart.
fn salient(dq: &DqLogs<'_>, options: &PmsmFitOptions, steady: &SteadyOptions) -> Option<Warning> {
    let ipm = steady_state_of(dq, options.pole_pairs, MotorKind::Ipm, steady).ok()?;
    let at = |name: &str| ipm.names.iter().position(|n| n == name);
    let (d, q) = (at("l_d")?, at("l_q")?);
    let (l_d, l_q, s_d, s_q) = (ipm.theta[d], ipm.theta[q], ipm.std_error[d], ipm.std_error[q]);
    let apart = (l_d - l_q).abs() / l_d.abs().max(l_q.abs());
    // The difference's standard error with the estimates' correlation.
    let var = s_d * s_d + s_q * s_q - 2.0 * ipm.correlation[d][q] * s_d * s_q;
    let z = (l_d - l_q).abs() / var.max(0.0).sqrt();
    (apart > SALIENCY && z > SALIENT_Z).then(|| {
        Warning::untrusted(
            "salient",
            format!(
                "the steady samples put L_d = {l_d:.4e} ± {s_d:.1e} H and L_q = {l_q:.4e} ± {s_q:.1e} H ({:.0} % \
                 apart, {z:.1} standard errors): the machine is salient, and the SPM equations move the \
                 difference into R_s and K_e; fit it with --model ipm",
                100.0 * apart
            ),
        )
    })
}
