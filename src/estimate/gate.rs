//! The trust gate: the checks every fit passes before it is called trusted (`greybox fit`
//! exits 0 only then), generic over every [`crate::model::GreyBoxModel`].
//!
//! A result is untrusted (a [`Warning`] with `untrusted`, each saying what to check) when:
//! - the solver did not report convergence (`not_converged`);
//! - it reported convergence, but the estimate is not a stationary point of the criterion:
//!   the Gauss–Newton step still to go, `δ = A⁻¹ g` (the bread `A` of the sandwich, the
//!   score `g` summed over the samples, both at the estimate), moves a parameter by more
//!   than [`STATIONARY_STEP`] of its standard error (`not_stationary`). A run stopped after
//!   one iteration by a step-size test cannot pass it: the test is on the point, not on the
//!   path (Dennis & Schnabel, *Numerical Methods for Unconstrained Optimization*, 1983,
//!   §7.2: stop on a small scaled gradient, not on a small step alone);
//! - the information matrix `JᵀWJ` in the optimiser's scaled coordinates is numerically
//!   singular: its condition number exceeds [`SINGULAR_CONDITION`], so some parameter
//!   combination does not change the prediction at all there (a plateau such as NIST
//!   StRD BoxBOD's from its first start, where `exp(−b₂x)` has vanished) (`singular`);
//! - an output's fit is below [`POOR_FIT_PERCENT`] while its residuals fail the Ljung–Box
//!   test: what the model leaves is structure, not noise (white residuals would make a low
//!   fit percentage the noise floor) (`poor_fit`). For a static model such a poor fit also
//!   refits four consecutive parts of the data ([`super::consistency::static_parts`]): a
//!   disagreement by Cochran's Q is structure too, whatever the order of the samples, and
//!   the warning names the parameters that disagree;
//! - the model declares a parameter value non-physical
//!   ([`crate::model::GreyBoxModel::implausible`]) (`non_physical`);
//! - the estimate is physical but a free model parameter's 95 % interval reaches values the
//!   model declares non-physical (`undetermined`): the data cannot tell the parameter from
//!   an impossible value, so the estimate is one point of a range that holds impossible
//!   ones, however honest the interval (slow telemetry whose intervals spanned zero left
//!   with exit 0 before: docs/warnings.md);
//! - a parameter sits at a bound (`parameter_at_bound`), unless every parameter at a bound
//!   is a nuisance parameter and the Gauss–Newton step to the unconstrained minimum is
//!   within [`BOUND_Z`] standard errors in every parameter (then `nuisance_at_bound`, a
//!   notice: the bound lies inside the intervals), or a statistic is not finite;
//! - a free parameter's standard error is exactly 0 while the loss is not
//!   (`zero_width_interval`): its interval claims a certainty the residual denies (the
//!   covariance's sums under- or overflowed).

use super::covariance::Inverse;
use super::problem::PemProblem;
use super::result::{FitStatistics, ParameterEstimate, SolverReport, Warning};
use super::solver::Gram;
use crate::model::GreyBoxModel;
use nalgebra::{DMatrix, DVector};

/// Largest Gauss–Newton step still to go at a converged estimate, in standard errors of
/// the parameter: well inside the interval, so the reported point is the minimum for every
/// purpose the interval serves.
pub const STATIONARY_STEP: f64 = 0.1;

/// Steps below this fraction of the parameter's magnitude are rounding, whatever their
/// standard error (a noise-free fit's is itself of the order of rounding).
pub const STEP_ROUNDING: f64 = 1e-9;

/// Largest Gauss–Newton step, in standard errors, from an estimate whose nuisance
/// parameter sits at a bound to the unconstrained minimum for the bound still to be inside
/// every 95 % interval (`nuisance_at_bound`, not untrusted; beyond it
/// `parameter_at_bound`).
pub const BOUND_Z: f64 = 1.96;

/// Condition number of the scaled information matrix above which it is numerically
/// singular: the normal equations lose 12 of double precision's 16 digits.
pub const SINGULAR_CONDITION: f64 = 1e12;

/// Fit percentage below which an output with coloured residuals is a poor fit (the same
/// level as the report's "poor fit" advice).
pub const POOR_FIT_PERCENT: f64 = 80.0;

/// What the gate looks at besides the report's parts.
#[derive(Debug)]
pub(crate) struct Evidence {
    /// Per free model parameter: its report name, the Gauss–Newton step still to go and
    /// the standard error, both in its unit.
    pub remaining: Vec<(String, f64, f64, f64)>,
    /// Condition number of `JᵀWJ` in the optimiser's scaled coordinates over the free model
    /// parameters (∞ when singular), and the parameters of its least-determined direction.
    pub condition: (f64, Vec<String>),
    /// The model's messages on non-physical values.
    pub implausible: Vec<String>,
    /// The free model parameters whose 95 % interval reaches values the model declares
    /// non-physical ([`undetermined`]), each described with its interval.
    pub undetermined: Vec<String>,
    /// Per output, whether its residuals pass the Ljung–Box test.
    pub white: Vec<bool>,
    /// The model's advice for a poor fit ([`crate::model::GreyBoxModel::poor_fit_advice`]).
    pub poor_fit_advice: Option<String>,
    /// A static model's check of a poor fit (`crate::estimate::consistency::static_parts`):
    /// `Some(None)` the fits of consecutive parts agree, `Some(Some(why))` they do not (a
    /// poor fit is then structure even with white residuals); `None` not run.
    pub parts: Option<Option<String>>,
}

/// The gate's warnings (module documentation), in a fixed order.
pub(crate) fn warnings(
    solver: &SolverReport,
    parameters: &[ParameterEstimate],
    fit: &FitStatistics,
    evidence: &Evidence,
) -> Vec<Warning> {
    let mut out = Vec::new();
    if !solver.success {
        out.push(Warning::untrusted(
            "not_converged",
            format!(
                "the solver did not converge ({}): the estimates are where it stopped",
                solver.termination
            ),
        ));
    }
    let bound: Vec<&ParameterEstimate> = parameters.iter().filter(|p| p.at_bound).collect();
    let at_bound: Vec<&str> = bound.iter().map(|p| p.name.as_str()).collect();
    let nuisance_only = !bound.is_empty() && bound.iter().all(|p| p.nuisance);
    if let Some(z) = inside_intervals(&evidence.remaining).filter(|_| nuisance_only) {
        out.push(Warning {
            code: "nuisance_at_bound".into(),
            message: format!(
                "{} at a bound (a nuisance parameter, no interval given): the unconstrained minimum lies within \
                 {z:.2} standard errors of the estimate in every parameter (at most {BOUND_Z}), so the bound is inside \
                 the intervals and binds no more than the noise does; the data do not tell the nuisance parameter \
                 from those it is correlated with",
                at_bound.join(", ")
            ),
            untrusted: false,
        });
    } else if !at_bound.is_empty() {
        out.push(Warning::untrusted(
            "parameter_at_bound",
            format!(
                "{} at a bound: the fit is constrained there, the minimum lies beyond it (wrong model, units or \
                 start?); no interval is given",
                at_bound.join(", ")
            ),
        ));
    }
    if solver.success && at_bound.is_empty() {
        out.extend(stationarity(&evidence.remaining));
    }
    let (condition, weak) = &evidence.condition;
    if *condition > SINGULAR_CONDITION {
        out.push(Warning::untrusted(
            "singular",
            format!(
                "the information matrix is numerically singular at the estimate (condition number {condition:.1e} in \
                 the scaled coordinates): changing {} does not change the prediction there (a plateau, or \
                 parameters the data cannot separate), so the estimate is one point of many. Start elsewhere, fix \
                 a parameter, or add data that excite it",
                if weak.is_empty() { "some parameter combination".to_string() } else { weak.join(" and ") }
            ),
        ));
    }
    let poor: Vec<String> = fit
        .outputs
        .iter()
        .zip(&fit.fit_percent)
        .zip(&evidence.white)
        .filter(|((_, f), white)| {
            let disagree = matches!(&evidence.parts, Some(Some(_)));
            let structured = !**white || disagree;
            **f < POOR_FIT_PERCENT && structured
        })
        .map(|((n, f), _)| format!("{n} {f:.1} %"))
        .collect();
    if !poor.is_empty() {
        let what = match &evidence.parts {
            Some(Some(why)) => format!("and fits of consecutive parts of the data that disagree ({why})"),
            _ => "with residuals that are not white".into(),
        };
        out.push(Warning::untrusted(
            "poor_fit",
            format!(
                "poor fit ({}) {what}: what the model leaves is structure it lacks, not noise: {}",
                poor.join(", "),
                evidence
                    .poor_fit_advice
                    .as_deref()
                    .unwrap_or("check the columns, units and signs of the log, and the model")
            ),
        ));
    }
    if !evidence.implausible.is_empty() {
        out.push(Warning::untrusted("non_physical", evidence.implausible.join("; ")));
    }
    if evidence.implausible.is_empty() {
        out.extend(undetermined_warning(&evidence.undetermined));
    }
    let stats = fit.fit_percent.iter().chain(&fit.rms_residual).chain([&fit.loss, &fit.mse]);
    let free_se = parameters.iter().filter(|p| !p.fixed && !p.at_bound).map(|p| &p.std_error);
    if stats.chain(free_se.clone()).any(|x| !x.is_finite()) {
        let outputs: Vec<&str> = fit
            .outputs
            .iter()
            .zip(&fit.fit_percent)
            .filter(|(_, f)| !f.is_finite())
            .map(|(n, _)| n.as_str())
            .collect();
        let why = if outputs.is_empty() {
            "a standard error is not finite (a parameter the data do not determine)".to_string()
        } else {
            format!("the fit percentage of {} is not finite (a constant output?)", outputs.join(", "))
        };
        out.push(Warning::untrusted("non_finite_statistics", why));
    }
    let zero: Vec<&str> = parameters
        .iter()
        .filter(|p| !p.fixed && !p.at_bound && p.std_error == 0.0)
        .map(|p| p.name.as_str())
        .collect();
    if !zero.is_empty() && fit.loss > 0.0 {
        out.push(Warning::untrusted(
            "zero_width_interval",
            format!(
                "the standard error of {} is exactly 0 while the residual is not: the covariance's sums under- or \
                 overflowed, so no interval is known (output weights far from 1? scale them towards 1)",
                zero.join(", ")
            ),
        ));
    }
    out
}

/// The untrusted `undetermined` warning of the parameters `described` (as
/// [`undetermined`] describes them); `None` for none.
pub(crate) fn undetermined_warning(described: &[String]) -> Option<Warning> {
    (!described.is_empty()).then(|| {
        Warning::untrusted(
            "undetermined",
            format!(
                "a 95 % interval reaches values the model declares non-physical: {}. The data do not tell such an \
                 estimate from an impossible value, so it is one point of a range that holds impossible ones: fix \
                 the parameter at a measured value, or add data that excite it",
                described.join("; ")
            ),
        )
    })
}

/// `not_stationary` when a parameter's remaining step exceeds [`STATIONARY_STEP`] standard
/// errors and [`STEP_ROUNDING`] of its magnitude. `remaining`: (name, value, step, se).
fn stationarity(remaining: &[(String, f64, f64, f64)]) -> Option<Warning> {
    let far: Vec<String> = remaining
        .iter()
        .filter(|(_, value, step, se)| {
            se.is_finite() && step.abs() > STATIONARY_STEP * se && step.abs() > STEP_ROUNDING * value.abs()
        })
        .map(|(name, _, step, se)| format!("{name} by {:.2} standard errors", step.abs() / se))
        .collect();
    (!far.is_empty()).then(|| {
        Warning::untrusted(
            "not_stationary",
            format!(
                "the solver stopped, but not at a minimum: a Gauss–Newton step from the estimate still moves {} \
                 (more than {STATIONARY_STEP}); raise --max-iters or tighten --xtol/--gtol",
                far.join(", ")
            ),
        )
    })
}

/// The largest Gauss–Newton step still to go in standard errors over the parameters of
/// `remaining` ([`Evidence::remaining`]) when it is at most [`BOUND_Z`] (the unconstrained
/// minimum inside every 95 % interval); `None` otherwise, without the steps, or where a
/// step or standard error is not a finite number (no interval to be inside).
fn inside_intervals(remaining: &[(String, f64, f64, f64)]) -> Option<f64> {
    let mut worst = None::<f64>;
    for (_, _, step, se) in remaining {
        let z = (step / se).abs();
        if !z.is_finite() {
            return None;
        }
        worst = Some(worst.map_or(z, |w| w.max(z)));
    }
    worst.filter(|w| *w <= BOUND_Z)
}

/// Per free model parameter in `order`: (name, value, Gauss–Newton step still to go, its
/// standard error), the step `A⁻¹ g` mapped to θ units; empty without the bread's inverse.
pub(crate) fn remaining(
    bread_inv: &Option<Inverse>,
    score: &DVector<f64>,
    order: &[usize],
    dtheta: &[f64],
    se: &[f64],
    names: &[String],
    value: impl Fn(usize) -> f64,
) -> Vec<(String, f64, f64, f64)> {
    let Some(ai) = bread_inv.as_ref().filter(|_| dtheta.len() == score.len()) else { return Vec::new() };
    let step = ai.apply_finite(score);
    order.iter().zip(names).map(|(&g, name)| (name.clone(), value(g), step[g] * dtheta[g], se[g])).collect()
}

/// Condition number of `JᵀWJ` (the optimiser's scaled coordinates) over the free model
/// parameters `order` (∞ when it is singular there) and the names of the parameters that
/// make up most (|component| ≥ 0.3) of its least-determined direction.
pub(crate) fn scaled_condition(jtj: &Gram, order: &[usize], names: &[String]) -> (f64, Vec<String>) {
    let sub = DMatrix::from_fn(order.len(), order.len(), |i, j| jtj[(order[i], order[j])]);
    if order.is_empty() || !sub.iter().all(|v| v.is_finite()) {
        return (f64::INFINITY, Vec::new());
    }
    let eig = sub.symmetric_eigen();
    let (mut lo, mut hi, mut at) = (f64::INFINITY, 0.0f64, 0);
    for (k, &v) in eig.eigenvalues.iter().enumerate() {
        if v < lo {
            (lo, at) = (v, k);
        }
        hi = hi.max(v);
    }
    let direction = eig.eigenvectors.column(at);
    let weak = direction.iter().zip(names).filter(|(c, _)| c.abs() >= 0.3).map(|(_, n)| n.clone()).collect();
    (if lo > 0.0 { hi / lo } else { f64::INFINITY }, weak)
}

/// The free model parameters (`parameters`' free entries, whose free indices are `order`,
/// [`crate::estimate::assemble`]'s order) whose 95 % interval reaches, at either end, a value
/// the model declares non-physical ([`GreyBoxModel::implausible`]) in an experiment's θ where
/// the estimate itself is physical, each as `name ∈ [lo, hi] unit` with the model's advice
/// on what excites it. Nuisance parameters, parameters at a bound and intervals that are
/// not finite are left out (no interval to read).
pub(crate) fn undetermined<M: GreyBoxModel>(
    problem: &PemProblem<'_, M>,
    p: &DVector<f64>,
    parameters: &[ParameterEstimate],
    order: &[usize],
) -> Vec<String> {
    let model = problem.model();
    let thetas: Vec<Vec<f64>> = (0..problem.terms().len()).map(|e| problem.theta(e, p)).collect();
    let mut out = Vec::new();
    for (q, &g) in parameters.iter().filter(|q| !q.fixed).zip(order) {
        let super::problem::FreeKind::Parameter(j) = problem.free()[g].kind else { continue };
        if q.nuisance || q.at_bound || !q.ci95.iter().all(|c| c.is_finite()) {
            continue;
        }
        let experiments = match problem.free()[g].experiment {
            Some(e) => e..e + 1,
            None => 0..thetas.len(),
        };
        let reaches = thetas[experiments].iter().any(|theta| {
            model.implausible(theta).is_empty()
                && q.ci95.iter().any(|&end| {
                    let mut at = theta.clone();
                    at[j] = end;
                    !model.implausible(&at).is_empty()
                })
        });
        if reaches {
            out.push(undetermined_entry(q, model.advice(&q.name)));
        }
    }
    out
}

/// One entry of [`undetermined`]'s list: `name ∈ [lo, hi] unit`, then the `advice` on what
/// excites the parameter in parentheses.
pub(crate) fn undetermined_entry(q: &ParameterEstimate, advice: Option<String>) -> String {
    let advice = advice.map(|a| format!(" ({a})")).unwrap_or_default();
    format!("{} ∈ [{:.4e}, {:.4e}] {}{advice}", q.name, q.ci95[0], q.ci95[1], q.unit)
}

/// The model's non-physical findings over every experiment's θ, each message once.
pub(crate) fn implausible<M: GreyBoxModel>(problem: &PemProblem<'_, M>, p: &DVector<f64>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for e in 0..problem.terms().len() {
        for m in problem.model().implausible(&problem.theta(e, p)) {
            if !out.contains(&m) {
                out.push(m);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::inside_intervals;

    /// The unconstrained minimum is inside the intervals only when every step is within
    /// `BOUND_Z` standard errors and each is a finite number.
    #[test]
    fn a_bound_is_inside_the_intervals_only_by_every_finite_step() {
        let r = |steps: &[(f64, f64)]| -> Vec<(String, f64, f64, f64)> {
            steps.iter().map(|&(step, se)| ("p".to_string(), 1.0, step, se)).collect()
        };
        assert_eq!(inside_intervals(&r(&[(0.1, 1.0), (-1.5, 1.0)])), Some(1.5));
        assert_eq!(inside_intervals(&r(&[(0.1, 1.0), (2.5, 1.0)])), None);
        assert_eq!(inside_intervals(&r(&[(0.0, 0.0), (0.1, 1.0)])), None, "0/0 is no interval");
        assert_eq!(inside_intervals(&r(&[(0.1, f64::NAN)])), None);
        assert_eq!(inside_intervals(&[]), None, "without the steps");
    }
}
