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
//! the damping's metric `D`); otherwise, or where the problem gives no `JᵀWε(q)`
//! ([`LeastSquares::directional_gradient`]) or the model cannot be simulated at `q`, the
//! plain step `δ`. The pass at `q` counts as one evaluation (`acceleration_count`).

use super::{Gram, LeastSquares, damped_solve, is_infeasible};
use argmin::core::Problem;
use nalgebra::DVector;

/// Finite-difference step along `δ` for the second directional derivative (Transtrum &
/// Sethna 2012, section 3: 0.1).
pub(super) const H: f64 = 0.1;

/// Largest ratio `2‖a‖_D / ‖δ‖_D` of an accepted acceleration (Transtrum & Sethna 2012:
/// 0.75).
pub(super) const ALPHA: f64 = 0.75;

/// Gain ratio below which the step after an accepted one is accelerated (a rejected step
/// always is): where the linear model predicted the cost well, the second-order term is
/// small and its pass wasted.
pub(super) const CURVED: f64 = 0.75;

/// The accelerated step `δ + a/2` from `p` (scaled space, length n), or `None` where the
/// plain step `delta` stands (see the module documentation). `jtj`, `jtr` the normal
/// equations at `p`, `d` the damping diagonal, `lambda` the damping.
///
/// # Errors
/// Every error of the problem's [`LeastSquares::directional_gradient`] other than an
/// unusable point ([`is_infeasible`]).
pub(super) fn accelerated<O: LeastSquares>(
    problem: &mut Problem<O>,
    p: &DVector<f64>,
    delta: &DVector<f64>,
    (jtj, jtr): (&Gram, &DVector<f64>),
    d: &DVector<f64>,
    lambda: f64,
) -> Result<Option<DVector<f64>>, argmin::core::Error> {
    let q = p + H * delta;
    let at_q = problem.problem("acceleration_count", |o| match o.directional_gradient(p, &q) {
        Ok(g) => Ok(g),
        Err(e) if is_infeasible(&e) => Ok(None),
        Err(e) => Err(e.into()),
    })?;
    let Some(at_q) = at_q.filter(|g| g.iter().all(|v| v.is_finite())) else {
        return Ok(None);
    };
    // −JᵀW r_vv, the right-hand side of the acceleration's damped normal equations.
    let rhs = ((&at_q - jtr) / H + jtj.mul(delta)) * (2.0 / H);
    let Some(a) = damped_solve(jtj, d, lambda, &rhs) else {
        return Ok(None);
    };
    let norm = |v: &DVector<f64>| v.iter().zip(d.iter()).map(|(x, dj)| dj * x * x).sum::<f64>().sqrt();
    let (velocity, acceleration) = (norm(delta), norm(&a));
    Ok((velocity > 0.0 && 2.0 * acceleration <= ALPHA * velocity).then(|| delta + 0.5 * a))
}
