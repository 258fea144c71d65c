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
//!
//! Parts that disagree beyond their standard errors but within the equations' accuracy
//! ([`EQUATIONS_ACCURACY`]) leave the fit trusted, with the intervals of the parameters they
//! disagree on widened by the parts' spread ([`Checked::spread`], [`widened`]): the
//! between-part standard deviation τ is added to the standard error in quadrature. This is
//! the form of a random-effects prediction interval (Higgins, Thompson & Spiegelhalter,
//! *J. R. Stat. Soc. A* 172, 2009), used as a heuristic: τ measures how much the equations'
//! error varies along the log, a lower bound on its size, not the size of an error common
//! to every part (which no refit of parts can see). Noise-free logs show what it is for
//! (every 20th row of a 10 kHz log of moves: R_s +0.0025 % with a standard error of 3e-6
//! relative, |z| 7.6; its four parts +0.0005 … +0.0035 %).

use crate::data::Experiment;
use crate::error::Error;
use crate::estimate::{FitResult, Homogeneity, Warning, disagreeing, homogeneity, widened_by_parts};
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

/// The family level of Cochran's Q below which the parts' spread widens a parameter's
/// interval ([`widened`]), divided by the number of parameters tested (Bonferroni): the
/// conventional 0.05, not the 1e-3 of the `segments_disagree` verdict. A widening is not a
/// verdict, and a test that misses a real spread leaves the interval too narrow (every
/// 20th row of a noise-free 5 kHz IPM log of moves: R_s's parts +0.0007 … +0.0052 %, Q at
/// p = 3.0e-4, just above the verdict's 2.5e-4 (1e-3 over four parameters), left R_s at
/// |z| 3.6 with exit 0; from another decimation offset p = 2.1e-4 and |z| 1.6). On a log
/// the equations fit, the parts pass it one time in twenty by chance, and then widen the
/// interval by their spread and Student's t: a precise fit may then exit 3 as imprecise
/// (every 20th row of a noisy 10 kHz SPM log, 100 seeds: 3 more fits exit 3 at 0.05, 16
/// more at 0.10).
pub const WIDENING_LEVEL: f64 = 0.05;

/// How many standard errors of `L_d − L_q` make an SPM log salient (with the inductances
/// more than [`SALIENCY`] apart).
pub const SALIENT_Z: f64 = 4.0;

/// What the steady-state fit's own data say about it ([`warnings`]).
#[derive(Clone, Debug, Default)]
pub(crate) struct Checked {
    /// The untrusted warnings: `segments_disagree`, `salient`.
    pub warnings: Vec<Warning>,
    /// The shared parameters on which the consecutive parts disagree beyond their standard
    /// errors (the p-value of Cochran's Q below [`WIDENING_LEVEL`] divided by the number of
    /// parameters tested, Bonferroni), whatever the size of the spread.
    pub spread: Vec<Homogeneity>,
}

/// The checks of the steady-state fit `est` of the logs `dq` against its own data: the
/// parts disagree beyond the equations' accuracy (`segments_disagree`, untrusted) or only
/// beyond their standard errors ([`Checked::spread`], for [`widened`]); the machine is
/// salient under an SPM fit (`salient`). `report` turns a part's estimate into a fit report.
pub(crate) fn warnings(
    dq: &DqLogs<'_>,
    options: &PmsmFitOptions,
    steady: &SteadyOptions,
    est: &SteadyEstimate,
    report: &dyn Fn(&SteadyEstimate, &[Experiment]) -> FitResult,
) -> Checked {
    let mut out = Vec::new();
    let mut spread = Vec::new();
    if let Ok(parts) = split_at_least(dq.experiments(), MIN_PART_SAMPLES) {
        // The control period is the drive's, the same along the log: the parts hold the
        // whole fit's estimate (a part's speeds may not separate it from K_e), and none
        // where the whole fit found none (`h_c2` not positive, or neglected): a part's
        // spurious `h_c2` would carry the currents' drift terms, first order in `h_c`.
        let h_c = est.value(PERIOD_TERM).filter(|c| *c > 0.0).map(f64::sqrt);
        let steady = &SteadyOptions {
            control_period: h_c.or(steady.control_period),
            estimate_period: false,
            ..steady.clone()
        };
        let fits: Vec<FitResult> = parts
            .iter()
            .filter_map(|logs| {
                steady_state(logs, options.pole_pairs, est.kind, steady).ok().map(|e| report(&e, logs))
            })
            .collect();
        let tests = homogeneity(&fits, 0.0);
        spread = disagreeing(&tests, 0.0, WIDENING_LEVEL).into_iter().cloned().collect();
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
    Checked { warnings: out, spread }
}

/// `est` with the standard error of every shared parameter in `spread` taken as
/// `√(σ² + τ²)`, `τ²` the parts' between-part variance ([`widened_by_parts`], Paule &
/// Mandel 1982), and its 95 % half width as Student's `t_0.975` with K − 1 degrees of
/// freedom (K the parts; τ is estimated from them), or with the parameter's own where
/// fewer ([`crate::estimate::Uncertainty::t_quantile_of`]), times that, with a note naming them;
/// `est` itself and no note when nothing is widened. The derived quantities (`k_t`,
/// `psi_f`, temperatures) take the widened standard errors, with the estimates' sampling
/// correlation.
///
/// Why `τ` and not `τ/√K` (the pooled mean's): the equations' error does not average out
/// over the parts; the whole log's estimate carries it as each part does.
pub(crate) fn widened(est: SteadyEstimate, spread: &[Homogeneity]) -> (SteadyEstimate, Option<String>) {
    let mut std_error = est.std_error.clone();
    let mut ci95 = est.ci95.clone();
    let mut named = Vec::new();
    for h in spread {
        let Some(j) = (0..est.names.len()).find(|&j| est.names[j] == h.name && est.experiment[j].is_none())
        else {
            continue;
        };
        let (tau, widened, half) = widened_by_parts(est.std_error[j], h);
        if tau.is_nan() || tau <= 0.0 {
            continue;
        }
        std_error[j] = widened;
        // The parts' t, or the parameter's own where its standard error rests on fewer.
        ci95[j] = half.max(est.uncertainty.t_quantile_of(j) * widened);
        named.push(format!("{} ({:.1e} relative)", h.name, tau / est.theta[j].abs()));
    }
    if named.is_empty() {
        return (est, None);
    }
    let note = format!(
        "the intervals of {} are widened by the spread of their estimates over {} consecutive parts of the logs \
         (τ, the between-part standard deviation of random-effects meta-analysis, Paule–Mandel; Student's t with \
         {} degrees of freedom): the parts disagree beyond their standard errors, though within the equations' \
         accuracy ({EQUATIONS_ACCURACY:e} relative), so the steady-state equations carry an error on these samples \
         that the covariance of the equation errors does not show",
        named.join(", "),
        spread[0].estimates.len(),
        spread[0].dof
    );
    (SteadyEstimate { std_error, ci95, ..est }, Some(note))
}

/// `est` with the central differences' truncation error in its intervals, and a note
/// saying how large it is: the steady-state equations read `di/dt` and `dω/dt` as
/// `(x[k+a] − x[k−a])/(2ah)`, whose error `(ah)² x'''/6` does not average out over the
/// samples, and which no interval of the equation errors shows (every 40th row of an
/// independent 5 kHz IPM log of short moves, noise-free: R_s −0.031 % at |z| 7.2, exit 0,
/// the same at every decimation offset). The same fit with the half width doubled
/// ([`SteadyOptions::derivative_half_width`]) carries four times that error, so
/// `b = (θ₂ − θ₁)/3` estimates the fit's own (Richardson extrapolation, e.g. Press et al.,
/// *Numerical Recipes*, 3rd ed., 2007, §5.7; on the logs above the doubled fit's error was
/// 2.9–4.2 times the default's). The instruments change with the width too, so `b` is the
/// estimates' sensitivity to it, a size rather than a correction: on a synthetic log whose
/// currents swing at ω h = 0.3, `b` of L_s is 2.9 times its error and of the other sign
/// (test `curving_telemetry_intervals_cover_the_central_differences_error`). It is added
/// to every standard error in quadrature, `√(σ² + b²)`, the half width keeping its
/// quantile, the correlations kept (as
/// [`widened`]'s: a bias common to the parameters would correlate them further, which the
/// derived quantities then understate); the estimate stays (the extrapolated one carries
/// the wider differences' noise). On a noisy log `b` holds the two fits' noise as well, a
/// small part of σ. `est` unchanged, with a note, when the doubled fit fails or ends with
/// other parameters (the period term neglected in one of them).
pub(crate) fn truncation(
    dq: &DqLogs<'_>,
    options: &PmsmFitOptions,
    steady: &SteadyOptions,
    est: SteadyEstimate,
) -> (SteadyEstimate, String) {
    let a = 2 * steady.derivative_half_width;
    let wide = SteadyOptions { derivative_half_width: a, ..steady.clone() };
    let wide = steady_state_of(dq, options.pole_pairs, est.kind, &wide).and_then(|w| {
        match w.names == est.names && w.experiment == est.experiment {
            true => Ok(w),
            false => Err(Error::Numerical {
                context: "steady-state fit".into(),
                reason: format!("it has the parameters {} instead", w.names.join(", ")),
            }),
        }
    });
    let wide = match wide {
        Ok(wide) => wide,
        Err(e) => {
            let note = format!(
                "the central differences' truncation error is not in the intervals: the fit with the differences \
                 over k ± {a} gives no estimate of it ({e})"
            );
            return (est, note);
        }
    };
    let n = est.theta.len();
    let b: Vec<f64> = (0..n).map(|j| (wide.theta[j] - est.theta[j]) / 3.0).collect();
    let (std_error, ci95) = in_quadrature(&est, (0..n).map(|j| (j, b[j])));
    let shown = |r: f64, text: String| if r.is_finite() { text } else { "—".to_string() };
    let sizes: Vec<String> = (0..n)
        .filter(|&j| est.names[j] != PERIOD_TERM)
        .map(|j| {
            let (relative, sigmas) = (b[j].abs() / est.theta[j].abs(), b[j].abs() / est.std_error[j]);
            let relative = shown(relative, format!("{relative:.1e}"));
            format!("{} {relative} ({} σ)", label(&est, j), shown(sigmas, format!("{sigmas:.2}")))
        })
        .collect();
    let note = format!(
        "the intervals include the central differences' truncation error, estimated by Richardson extrapolation \
         from the fit with the differences over k ± {a} (four times the error: b = (θ₂ − θ₁)/3, added to the \
         standard error in quadrature); relative to each estimate and in the standard errors before it: {}",
        sizes.join(", ")
    );
    (SteadyEstimate { std_error, ci95, ..est }, note)
}

/// `est` with the steady-state equations' own accuracy on an exact log in its intervals,
/// and a note naming the parameters it widens: [`EQUATIONS_ACCURACY`] read as the bound of
/// a rectangular distribution, a standard uncertainty `EQUATIONS_ACCURACY/√3` relative to
/// each estimate (a Type B evaluation: JCGM 100:2008, *Guide to the expression of
/// uncertainty in measurement*, §4.3.7), added in quadrature to the standard error of every
/// parameter but the period term's, the half width keeping its quantile. The parts' check
/// takes spreads within that accuracy as agreement, so an interval narrower than it claims
/// what the fit does not check (every 20th row of a noise-free 5 kHz IPM log of moves, the
/// 2 s from 6 to 8 s: L_q +0.004 % at |z| 15, L_d +0.015 % at |z| 4.5; the window too
/// short for the parts' check). Only where it adds a tenth of the standard error or more
/// (below that it changes the standard error by under 0.5 %): `est` unchanged on a noisy
/// log, with no note.
pub(crate) fn accuracy(est: SteadyEstimate) -> (SteadyEstimate, Option<String>) {
    let u: Vec<f64> = (0..est.theta.len())
        .map(|j| match est.names[j] == PERIOD_TERM {
            true => 0.0,
            false => EQUATIONS_ACCURACY / 3f64.sqrt() * est.theta[j].abs(),
        })
        .collect();
    let widen: Vec<usize> =
        (0..u.len()).filter(|&j| u[j].is_finite() && u[j] > 0.0 && u[j] >= 0.1 * est.std_error[j]).collect();
    if widen.is_empty() {
        return (est, None);
    }
    let (std_error, ci95) = in_quadrature(&est, widen.iter().map(|&j| (j, u[j])));
    let named: Vec<String> = widen.iter().map(|&j| label(&est, j)).collect();
    let note = format!(
        "the intervals of {} include the steady-state equations' own accuracy on an exact log ({EQUATIONS_ACCURACY:e} \
         relative, the parts' check's bound, as a rectangular distribution: {:.1e} relative added to the standard \
         error in quadrature), which their standard errors alone would claim to beat",
        named.join(", "),
        EQUATIONS_ACCURACY / 3f64.sqrt()
    );
    (SteadyEstimate { std_error, ci95, ..est }, Some(note))
}

/// The standard errors and 95 % half widths of `est` with each `(j, b)` of `extra` added
/// to parameter `j`'s standard error in quadrature, `√(σ² + b²)` (units of the parameter),
/// the half width keeping its quantile (scaled by the standard error's growth; Student's
/// t with the parameter's degrees of freedom where σ was 0); the other parameters' as they
/// were.
fn in_quadrature(est: &SteadyEstimate, extra: impl Iterator<Item = (usize, f64)>) -> (Vec<f64>, Vec<f64>) {
    let (mut std_error, mut ci95) = (est.std_error.clone(), est.ci95.clone());
    for (j, b) in extra {
        std_error[j] = est.std_error[j].hypot(b);
        ci95[j] = match est.std_error[j] > 0.0 {
            true => est.ci95[j] * std_error[j] / est.std_error[j],
            false => est.uncertainty.t_quantile_of(j) * std_error[j],
        };
    }
    (std_error, ci95)
}

/// Parameter `j` of `est` as the report names it: `name`, or `name[log]` for a per-log one.
pub(super) fn label(est: &SteadyEstimate, j: usize) -> String {
    match &est.experiment[j] {
        Some(e) => format!("{}[{e}]", est.names[j]),
        None => est.names[j].clone(),
    }
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
