//! Geodesic acceleration of the Levenberg-Marquardt step (Transtrum & Sethna,
//! "Improvements to the Levenberg-Marquardt algorithm for nonlinear least-squares
//! minimization", arXiv:1201.5885, 2012, section 3; Transtrum, Machta & Sethna, *Phys.
//! Rev. E* 83, 036701, 2011).
//!
//! The damped step `δ = (JᵀWJ + λD)⁻¹ JᵀWε` is the first-order term of a path along the
//! model manifold; in a narrow curved valley it points off the valley floor, and the damping
//! then shortens it to a crawl (MGH's Rosenbrock from 100 times its start took 142
//! evaluations, MINPACK's trust region 6). The second-order term, the acceleration
//! `a = −(JᵀWJ + λD)⁻¹ JᵀW r_vv`, bends the step along the valley; `r_vv`, the second
//! directional derivative of the residual `r = ŷ − y = −ε` along `δ`, is taken by a finite
//! difference at `q = p + hδ`:
//!
//! ```text
//! r_vv ≈ (2/h) [ (r(q) − r(p))/h − J δ ]
//! JᵀW r_vv = (2/h) [ (JᵀWε(p) − JᵀWε(q))/h − JᵀWJ δ ]     (J at p)
//! ```
//!
//! with `h = 0.1` (the paper's). The step is `δ + a/2`, taken only while the acceleration
//! is small against the velocity, `2‖a‖_D / ‖δ‖_D ≤ α = 0.75` (the paper's criterion, in
//! the damping's metric `D`). Where it is not, the paper rejects the step and raises λ;
//! here the plain step `δ` is evaluated instead, as it is where the problem gives no
//! `JᵀWε(q)` ([`LeastSquares::directional_gradient`]) or the model cannot be simulated at
//! `q`. An acceleration counts as two evaluations (a residual pass at `q`, a Jacobian pass
//! at `p`; `acceleration_count`); one the problem does not give counts none.

use super::{Gram, LeastSquares, Monitor, damped_solve, is_infeasible};
use argmin::core::Problem;
use nalgebra::DVector;

/// Finite-difference step along `δ` for the second directional derivative (Transtrum &
/// Sethna 2012, section 3: 0.1).
const H: f64 = 0.1;

/// The evaluation counter the acceleration's passes are added to (summed into
/// [`crate::estimate::SolverReport::evaluations`]).
pub(super) const COUNT: &str = "acceleration_count";

/// Passes one acceleration costs: the residuals at `q` and the Jacobian at `p` (the
/// prediction-error problem does not keep the Jacobian between passes).
const PASSES: u64 = 2;

/// Largest ratio `2‖a‖_D / ‖δ‖_D` of an accepted acceleration (Transtrum & Sethna 2012:
/// 0.75).
const ALPHA: f64 = 0.75;

/// Gain ratio below which the step after an accepted one is accelerated (a rejected step
/// always is): where the linear model predicted the cost well, the second-order term is
/// small and its pass wasted.
pub(super) const CURVED: f64 = 0.75;

/// The accelerated step `δ + a/2` from `p` (scaled space, length n), or `None` where the
/// plain step `delta` stands (see the module documentation). `jtj`, `jtr` the normal
/// equations at `p`, `monitor` the run's damping diagonal `D` and its norm, `lambda` the
/// damping.
///
/// # Errors
/// Every error of the problem's [`LeastSquares::directional_gradient`] other than an
/// unusable point ([`is_infeasible`]).
pub(super) fn accelerated<O: LeastSquares>(
    problem: &mut Problem<O>,
    p: &DVector<f64>,
    delta: &DVector<f64>,
    (jtj, jtr): (&Gram, &DVector<f64>),
    monitor: &Monitor,
    lambda: f64,
) -> Result<Option<DVector<f64>>, argmin::core::Error> {
    let q = p + H * delta;
    let Some(o) = problem.problem.as_ref() else {
        return Ok(None);
    };
    let at_q = match o.directional_gradient(p, &q) {
        Ok(g) => g,
        Err(e) if is_infeasible(&e) => None,
        Err(e) => return Err(e.into()),
    };
    let Some(at_q) = at_q else {
        return Ok(None);
    };
    // The residual pass at q and the Jacobian at p: two passes, as two evaluations.
    *problem.counts.entry(COUNT).or_insert(0) += PASSES;
    if at_q.iter().any(|v| !v.is_finite()) {
        return Ok(None);
    }
    // −JᵀW r_vv, the right-hand side of the acceleration's damped normal equations.
    let rhs = ((&at_q - jtr) / H + jtj.mul(delta)) * (2.0 / H);
    let Some(a) = damped_solve(jtj, monitor.diag(), lambda, &rhs) else {
        return Ok(None);
    };
    let (velocity, acceleration) = (monitor.norm(delta), monitor.norm(&a));
    Ok((velocity > 0.0 && 2.0 * acceleration <= ALPHA * velocity).then(|| delta + 0.5 * a))
}
