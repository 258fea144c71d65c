//! MINPACK's convergence tests, shared by the solvers (`lmder`, Moré, Garbow & Hillstrom,
//! *User guide for MINPACK-1*, ANL-80-74, 1980, section 2.3; Moré, "The Levenberg-Marquardt
//! algorithm: implementation and theory", *Numerical Analysis*, LNM 630, 1978, section 7).
//!
//! - `ftol`: `|actred| ≤ ftol`, `prered ≤ ftol` and `½ ρ ≤ 1`, with the relative actual
//!   reduction `actred = (V − V_new)/V` (−1 when the trial point is unusable or
//!   `V_new ≥ 100 V`, as MINPACK's `0.1 ‖r_new‖ ≥ ‖r‖`), the relative reduction predicted
//!   by the quadratic model `prered = (−∇Vᵀδ − ½ δᵀJᵀWJδ)/V` and `ρ = actred/prered`;
//!   MINPACK tests it after every trial step, accepted or not; the solvers here test it
//!   after accepted steps (and Gauss-Newton after a failed full step).
//! - `xtol`: `‖δ‖_D ≤ xtol ‖p‖_D` for the step δ just tried, p the point after it (MINPACK
//!   tests its trust radius Δ, which after the step is of the order of `‖δ‖_D`: at most
//!   `2‖δ‖_D` after a good step, less after a poor one).
//! - `gtol`: the cosine `max_j |J_jᵀWε| / (‖J_j‖ ‖√W ε‖) ≤ gtol`, columns with `J_j = 0`
//!   left out, at every accepted point.
//! - zero residual, not MINPACK's: `0 ≤ V ≤ ε_mach² min(V₀, 1)` at an accepted point
//!   ([`Monitor::zero_residual`], NL2SOL's absolute function convergence test).
//!
//! `‖x‖_D = √(Σ d_j x_j²)` with `d_j` the largest `‖J_j‖²` met so far, 1 for a column
//! never non-zero: the square of MINPACK's `diag` with `mode = 1` (Moré 1978, eq. 6.3).
//!
//! A safeguard MINPACK lacks: a convergence test passing where the Jacobian has vanished
//! (every `‖J_j‖² ≤ ε_mach` × its largest value met, the test ratios are 0/0) at a cost
//! far from zero (`V > ε_mach V₀`) is reported as [`Termination::ZeroJacobian`], never as
//! success.

use super::{Gram, LeastSquares, LsState, Termination, Tolerances};
use crate::error::Error;
use argmin::core::{Problem, TerminationReason, TerminationStatus};
use nalgebra::DVector;
use serde::{Deserialize, Serialize};

/// The error for a state the solver should have filled in `init` (never a panic).
pub(crate) fn missing(solver: &str, what: &str) -> argmin::core::Error {
    Error::Solver(format!("{solver}: no {what} in the solver state (init not run?)")).into()
}

/// The scaling and the reference values of the convergence tests of one run.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub(crate) struct Monitor {
    /// `d_j`: the largest `‖J_j‖²` met, 1 for columns never non-zero (MINPACK's `diag²`).
    diag: DVector<f64>,
    /// The largest `‖J_j‖²` met, without the fill: the reference of "vanished".
    peak: DVector<f64>,
    /// Cost at the start V₀.
    cost0: f64,
    /// `‖δ‖_D` of the last accepted step (none before the first).
    last_step: Option<f64>,
}

/// Relative reductions of a trial step (see the module documentation).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reductions {
    /// Actual relative reduction `actred`.
    pub actred: f64,
    /// Predicted relative reduction `prered`.
    pub prered: f64,
    /// `ρ = actred/prered` (0 when `prered = 0`).
    pub ratio: f64,
}

impl Monitor {
    /// Starts a run at cost V₀ and `JᵀWJ` at the start.
    fn start(&mut self, cost0: f64, jtj: &Gram) {
        self.cost0 = cost0;
        self.last_step = None;
        self.peak = jtj.diagonal().map(|d| d.max(0.0));
        self.diag = self.peak.map(|d| if d > 0.0 { d } else { 1.0 });
    }

    /// Takes in `JᵀWJ` at a new point (the running maxima).
    pub fn observe(&mut self, jtj: &Gram) {
        if self.diag.len() != jtj.nrows() {
            self.start(self.cost0, jtj);
            return;
        }
        for j in 0..self.diag.len() {
            let h = jtj[(j, j)];
            if h > self.peak[j] {
                self.peak[j] = h;
            }
            if h > self.diag[j] {
                self.diag[j] = h;
            }
        }
    }

    /// The scaling `d_j` (length n_free, all > 0).
    pub fn diag(&self) -> &DVector<f64> {
        &self.diag
    }

    /// `‖x‖_D`.
    pub fn norm(&self, x: &DVector<f64>) -> f64 {
        x.iter().zip(self.diag.iter()).map(|(x, d)| d * x * x).sum::<f64>().sqrt()
    }

    /// MINPACK's `xtol` test on the next step δ from p.
    pub fn small_step(&self, tol: &Tolerances, step: &DVector<f64>, p: &DVector<f64>) -> bool {
        self.norm(step) <= tol.xtol * self.norm(p)
    }

    /// Whether a trial step δ to `trial`, whose relative reduction the quadratic model
    /// predicts as `prered`, likely ends the run once accepted: it passes the xtol test
    /// itself, or its predicted reduction is below ftol, or the step after it, extrapolated
    /// from the last two as superlinear convergence has it (`‖δ‖²_D / ‖δ_prev‖_D`), would
    /// pass the xtol test. Only a hint (what the solver asks of the trial's evaluation); the
    /// tests that end the run are the others here.
    pub fn likely_last(
        &self,
        tol: &Tolerances,
        step: &DVector<f64>,
        trial: &DVector<f64>,
        prered: f64,
    ) -> bool {
        let (norm, bound) = (self.norm(step), tol.xtol * self.norm(trial));
        norm <= bound || prered <= tol.ftol || self.last_step.is_some_and(|prev| norm * norm <= bound * prev)
    }

    /// Takes in an accepted step δ (for [`likely_last`](Self::likely_last)).
    pub fn accept_step(&mut self, step: &DVector<f64>) {
        self.last_step = Some(self.norm(step));
    }

    /// The reductions of a step from a point of cost `cost` to one of cost `new_cost`
    /// (`None`: unusable), the quadratic model predicting a decrease by `predicted`.
    pub fn reductions(cost: f64, new_cost: Option<f64>, predicted: f64) -> Reductions {
        let actred = match new_cost {
            Some(c) if c.is_finite() && c < 100.0 * cost => (cost - c) / cost,
            _ => -1.0,
        };
        let prered = predicted / cost;
        let ratio = if prered != 0.0 { actred / prered } else { 0.0 };
        Reductions { actred, prered, ratio }
    }

    /// Whether `cost` is a zero residual to working precision: `V ≤ ε_mach² min(V₀, 1)`,
    /// i.e. `‖√W ε‖ ≤ ε_mach ‖√W ε₀‖` and `‖√W ε‖ ≤ √2 ε_mach` (0 included). NL2SOL's
    /// absolute function convergence test (`V ≤ AFCTOL`, Dennis, Gay & Welsch, *ACM TOMS* 7
    /// (1981) 348–368; PORT's default `max(1e-20, ε_mach²)`) at `ε_mach²`, bounded by the start's
    /// cost so that it never passes at a start in small units. MINPACK has no such test and
    /// relies on `V = 0` or on its `gtol`/`xtol` tests: where the Jacobian is singular at a zero
    /// residual (Powell's singular function) the iteration converges linearly, S falling
    /// 16-fold a step, no test passes in exact arithmetic, and MINPACK ends where rounding
    /// makes its `gnorm` pass (`info` 8); past `ε_mach²` nothing is left to gain. A negative
    /// cost (a bias-compensated criterion `V − c`, `crate::estimate::correction`) is no zero
    /// residual. Where `V₀ ≥ 1` the bound is absolute: it assumes weighted data `‖√W y‖` not far
    /// below 1, as SI drive logs with the default weights are.
    pub fn zero_residual(&self, cost: f64) -> bool {
        (0.0..=f64::EPSILON * f64::EPSILON * self.cost0.min(1.0)).contains(&cost)
    }

    /// MINPACK's `ftol` test (`info = 1`).
    pub fn cost_converged(tol: &Tolerances, r: &Reductions) -> bool {
        r.actred.abs() <= tol.ftol && r.prered <= tol.ftol && 0.5 * r.ratio <= 1.0
    }

    /// MINPACK's `gtol` test at a point.
    pub fn gradient_converged(tol: &Tolerances, jtj: &Gram, jtr: &DVector<f64>, cost: f64) -> bool {
        scaled_gradient(jtj, jtr, cost) <= tol.gtol
    }

    /// `t`, unless it claims convergence at a point where the Jacobian has vanished at a
    /// cost far from zero: then [`Termination::ZeroJacobian`].
    pub fn certify(&self, t: Termination, jtj: &Gram, cost: f64) -> Termination {
        let claims = t.success() && t != Termination::ZeroResidual;
        let far = cost > f64::EPSILON * self.cost0;
        let vanished = (0..jtj.nrows()).all(|j| {
            let peak = self.peak.get(j).copied().unwrap_or(0.0);
            jtj[(j, j)] <= f64::EPSILON * peak
        });
        if claims && far && vanished { Termination::ZeroJacobian } else { t }
    }
}

/// The point an iteration starts from, taken out of the solver state: `p`, `∇V`, `JᵀWJ`
/// and the cost `V` (the state keeps the cost).
///
/// # Errors
/// A state `init` did not fill ([`missing`], naming `solver`).
pub(crate) fn take_point(
    state: &mut LsState,
    solver: &str,
) -> Result<(DVector<f64>, DVector<f64>, Gram, f64), argmin::core::Error> {
    let p = state.take_param().ok_or_else(|| missing(solver, "parameter"))?;
    let grad = state.take_gradient().ok_or_else(|| missing(solver, "gradient"))?;
    let jtj = state.take_hessian().ok_or_else(|| missing(solver, "JᵀWJ"))?;
    Ok((p, grad, jtj, state.get_cost()))
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
/// equations there, starts the monitor and fills the state (`p`, cost, `∇V`, `JᵀWJ`,
/// `max_iters`). Returns the state and a termination when the start is already a solution
/// (zero residual or gradient within `gtol`).
///
/// # Errors
/// No start vector in the state; a non-finite cost at the start; every error of
/// [`LeastSquares::normal_equations`] (at the start, infeasibility is an error).
pub(crate) fn init_state<O: LeastSquares>(
    problem: &mut Problem<O>,
    mut state: LsState,
    tol: &Tolerances,
    monitor: &mut Monitor,
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
    monitor.start(ne.cost, &ne.jtj);
    let t = if ne.cost == 0.0 {
        Some(Termination::ZeroResidual)
    } else if Monitor::gradient_converged(tol, &ne.jtj, &ne.jtr, ne.cost) {
        Some(monitor.certify(Termination::GradientTolerance, &ne.jtj, ne.cost))
    } else {
        None
    };
    let gradient = ne.gradient();
    Ok((state.param(p).cost(ne.cost).gradient(gradient).hessian(ne.jtj).max_iters(tol.max_iters), t))
}

/// MINPACK's scaled gradient norm: `max_j |g_j| / (√H_jj ‖r‖)`, with `‖r‖² = 2 cost`;
/// columns with `H_jj = 0` are left out.
fn scaled_gradient(jtj: &Gram, jtr: &DVector<f64>, cost: f64) -> f64 {
    let rnorm = (2.0 * cost).sqrt();
    (0..jtr.len())
        .map(|j| {
            let c = jtj[(j, j)].sqrt();
            if c > 0.0 && rnorm > 0.0 { jtr[j].abs() / (c * rnorm) } else { 0.0 }
        })
        .fold(0.0, f64::max)
}

/// Solves `(H + λ D) δ = g` by Cholesky (an arrowhead H by its Schur complement); `None`
/// when the matrix is not positive definite.
pub(crate) fn damped_solve(
    h: &Gram,
    d: &DVector<f64>,
    lambda: f64,
    g: &DVector<f64>,
) -> Option<DVector<f64>> {
    h.damped_solve(d, lambda, g)
}
