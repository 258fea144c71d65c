//! What the least-squares solvers need from a problem, their tolerances and how they stop.

use crate::error::{Error, Result};
use crate::estimate::lm::LsState;
use crate::estimate::problem::{NormalEquations, PemProblem};
use crate::model::GreyBoxModel;
use argmin::core::{Problem, TerminationReason, TerminationStatus};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// A nonlinear least-squares problem in scaled variables p, as the solvers see it.
pub trait LeastSquares {
    /// Number of free parameters n_p.
    fn n_params(&self) -> usize;
    /// Cost `V(p) = ½ εᵀWε` with `JᵀWJ` and `JᵀWε` (`J = ∂ŷ/∂p`).
    ///
    /// # Errors
    /// [`Error::SimulationDiverged`] or [`Error::InvalidParameter`] at a point the model
    /// cannot simulate (the solvers treat these as an infinite cost at trial points);
    /// anything else aborts the fit.
    fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations>;
    /// Cost `V(p)` alone.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    fn cost(&self, p: &DVector<f64>) -> Result<f64>;
    /// Projects p onto the feasible box in place.
    fn project(&self, p: &mut DVector<f64>);
}

impl<M: GreyBoxModel> LeastSquares for PemProblem<'_, M> {
    fn n_params(&self) -> usize {
        self.n_free()
    }
    fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        PemProblem::normal_equations(self, p)
    }
    fn cost(&self, p: &DVector<f64>) -> Result<f64> {
        PemProblem::cost(self, p)
    }
    fn project(&self, p: &mut DVector<f64>) {
        PemProblem::project(self, p)
    }
}

/// Whether an evaluation error only means "this trial point is unusable".
pub(crate) fn is_infeasible(e: &Error) -> bool {
    matches!(e, Error::SimulationDiverged { .. } | Error::InvalidParameter { .. })
}

/// Stopping tolerances shared by the solvers (MINPACK conventions, Moré et al. 1980).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Tolerances {
    /// Stop when an accepted step lowers the cost by at most `ftol × cost` (relative).
    pub ftol: f64,
    /// Stop when the step satisfies `‖δ‖ ≤ xtol (‖p‖ + xtol)` (scaled space).
    pub xtol: f64,
    /// Stop when `max_j |J_jᵀWε| / (‖J_j‖ ‖√W ε‖) ≤ gtol` (cosine of residual and columns).
    pub gtol: f64,
    /// Maximum number of iterations (trial steps).
    pub max_iters: u64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Self { ftol: 1e-12, xtol: 1e-10, gtol: 1e-10, max_iters: 200 }
    }
}

impl Tolerances {
    /// Checks that every tolerance is finite and ≥ 0 and `max_iters ≥ 1`.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming the tolerance.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("ftol", self.ftol), ("xtol", self.xtol), ("gtol", self.gtol)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::InvalidOption {
                    option: name.into(),
                    reason: format!("must be finite and ≥ 0, got {v}"),
                });
            }
        }
        if self.max_iters == 0 {
            return Err(Error::InvalidOption {
                option: "max_iters".into(),
                reason: "must be at least 1".into(),
            });
        }
        Ok(())
    }
}

/// Why a solver stopped.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The gradient is orthogonal to the residual within `gtol` (a stationary point).
    GradientTolerance,
    /// The step fell below `xtol`.
    StepTolerance,
    /// The relative cost reduction fell below `ftol`.
    CostTolerance,
    /// The residual is exactly zero.
    ZeroResidual,
    /// `max_iters` reached before convergence.
    MaxIterations,
    /// No step along the search direction lowers the cost (line search failed).
    NoDescent,
    /// argmin stopped the run (timeout, interrupt, target cost).
    Stopped(String),
}

impl Termination {
    /// Whether the fit converged.
    pub fn success(&self) -> bool {
        matches!(
            self,
            Self::GradientTolerance | Self::StepTolerance | Self::CostTolerance | Self::ZeroResidual
        )
    }
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::GradientTolerance => f.write_str("converged: gradient tolerance"),
            Self::StepTolerance => f.write_str("converged: step tolerance"),
            Self::CostTolerance => f.write_str("converged: relative cost reduction below tolerance"),
            Self::ZeroResidual => f.write_str("converged: zero residual"),
            Self::MaxIterations => f.write_str("not converged: maximum number of iterations reached"),
            Self::NoDescent => f.write_str("not converged: no descent along the search direction"),
            Self::Stopped(s) => write!(f, "not converged: stopped by the executor ({s})"),
        }
    }
}

/// A solver that records why it stopped, so that the fit report can say so.
pub trait ReportsTermination {
    /// Why the solver stopped, once it has; `None` while running or when argmin stopped it
    /// (iteration limit, timeout, interrupt).
    fn termination(&self) -> Option<&Termination>;
}

/// argmin's status for a solver's own termination reason (`None` = keep going).
pub(crate) fn status(t: Option<&Termination>) -> TerminationStatus {
    match t {
        Some(t) if t.success() => TerminationStatus::Terminated(TerminationReason::SolverConverged),
        Some(t) => TerminationStatus::Terminated(TerminationReason::SolverExit(t.to_string())),
        None => TerminationStatus::NotTerminated,
    }
}

/// The common start of the solvers: projects the start vector, evaluates the normal
/// equations there and fills the state (`p`, cost, `JᵀWε`, `JᵀWJ`, `max_iters`). Returns
/// the state and a termination when the start is already a solution (zero residual or
/// gradient within `gtol`).
///
/// # Errors
/// No start vector in the state; a non-finite cost at the start; every error of
/// [`LeastSquares::normal_equations`] (at the start, infeasibility is an error).
pub(crate) fn init_state<O: LeastSquares>(
    problem: &mut Problem<O>,
    mut state: LsState,
    tol: &Tolerances,
) -> std::result::Result<(LsState, Option<Termination>), argmin::core::Error> {
    let mut p = state.take_param().ok_or_else(|| Error::Solver("no start vector".into()))?;
    problem.problem("project_count", |o| {
        o.project(&mut p);
        Ok(())
    })?;
    let ne = problem.problem("normal_equations_count", |o| Ok(o.normal_equations(&p)?))?;
    if !ne.cost.is_finite() {
        return Err(Error::Solver(format!("cost at the start is {}", ne.cost)).into());
    }
    let t = if ne.cost == 0.0 {
        Some(Termination::ZeroResidual)
    } else if scaled_gradient(&ne.jtj, &ne.jtr, ne.cost) <= tol.gtol {
        Some(Termination::GradientTolerance)
    } else {
        None
    };
    Ok((state.param(p).cost(ne.cost).gradient(ne.jtr).hessian(ne.jtj).max_iters(tol.max_iters), t))
}

/// MINPACK's scaled gradient norm: `max_j |g_j| / (√H_jj ‖r‖)`, with `‖r‖² = 2 cost`.
pub(crate) fn scaled_gradient(jtj: &DMatrix<f64>, jtr: &DVector<f64>, cost: f64) -> f64 {
    let rnorm = (2.0 * cost).sqrt();
    (0..jtr.len())
        .map(|j| {
            let c = jtj[(j, j)].sqrt();
            if c > 0.0 && rnorm > 0.0 { jtr[j].abs() / (c * rnorm) } else { 0.0 }
        })
        .fold(0.0, f64::max)
}

/// Solves `(H + λ D) δ = g` by Cholesky; `None` when the matrix is not positive definite.
pub(crate) fn damped_solve(
    h: &DMatrix<f64>,
    d: &DVector<f64>,
    lambda: f64,
    g: &DVector<f64>,
) -> Option<DVector<f64>> {
    let mut a = h.clone();
    for j in 0..a.nrows() {
        a[(j, j)] += lambda * d[j];
    }
    a.cholesky().map(|c| c.solve(g))
}

impl<T: LeastSquares + ?Sized> LeastSquares for &T {
    fn n_params(&self) -> usize {
        (**self).n_params()
    }
    fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        (**self).normal_equations(p)
    }
    fn cost(&self, p: &DVector<f64>) -> Result<f64> {
        (**self).cost(p)
    }
    fn project(&self, p: &mut DVector<f64>) {
        (**self).project(p)
    }
}
