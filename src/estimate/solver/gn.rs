//! Damped Gauss-Newton with a backtracking (Armijo) line search, as an argmin [`Solver`].
//!
//! Each iteration solves the Gauss-Newton normal equations `JᵀWJ δ = −∇V = JᵀWε` by Cholesky
//! (no inverse). When `JᵀWJ` is not positive definite (a parameter the data do not
//! determine), a Levenberg-style shift `μ D`, `D = diag(JᵀWJ)`, is added with μ growing
//! ×10 from 1e-12 until the factorisation succeeds; the KV entry `shift` reports μ.
//! Parameters pressed against a bound are held there and the normal equations solved for
//! the others (KV `held`), so that δ is a descent direction of the bounded problem.
//!
//! The step length α starts at 1 and shrinks by the backtracking factor (½) until the
//! projected trial point `p_α = P(p + α δ)` (a parameter bounded above 0 that the step
//! takes past zero put at a hundredth of its value, [`LeastSquares::project_trial`]) meets the sufficient-decrease (Armijo)
//! condition `V(p_α) ≤ V(p) + c₁ ∇Vᵀ(p_α − p)` (`∇V = −JᵀWε`) and lowers
//! the cost: a cost increase is never accepted. The search evaluates the cost alone
//! ([`LeastSquares::cost`]); the normal equations are evaluated once, at the accepted
//! point. Trial points where the model cannot be simulated count as failed trials.
//!
//! Stopping uses the tests of the Levenberg-Marquardt solver
//! ([`super::lm::LevenbergMarquardt`], MINPACK's, [`Tolerances`]): `gtol` on the
//! scaled gradient at every accepted point, `xtol` on the full projected Gauss-Newton step
//! (α = 1) in the D-scaled norm, tried first (taken if it lowers the cost), `ftol` on the actual and predicted relative reductions of
//! the accepted step and of a failed full step (a failed full step whose reductions are
//! both below `ftol` means the cost sits at its rounding floor: MINPACK's `info = 1` on a
//! rejected step), and [`Termination::NoDescent`] when α falls below its minimum (1e-10).
//! A test passing where the Jacobian has vanished at a cost far from zero gives
//! [`Termination::ZeroJacobian`]: with `JᵀWJ = 0` the step is undefined and a zero
//! gradient certifies nothing.
//!
//! Sources: Dennis & Schnabel, *Numerical Methods for Unconstrained Optimization and
//! Nonlinear Equations*, 1983, section 6.3 (backtracking line search) and 10.2 (damped
//! Gauss-Newton); Nocedal & Wright, *Numerical Optimization*, 2nd ed., 2006, sections 3.1
//! (Armijo condition, backtracking) and 10.3 (Gauss-Newton); Björck, *Numerical Methods
//! for Least Squares Problems*, 1996, section 9.2 (damped Gauss-Newton) and 5.2 (bounds).

use super::Gram;
use super::{
    LeastSquares, LsState, Monitor, NormalEquations, ReportsTermination, Termination, Tolerances,
    damped_solve, init_state, is_infeasible, status, take_point, trial_normal_equations,
};
use argmin::core::{KV, Problem, Solver, TerminationStatus};
use nalgebra::DVector;
use serde::{Deserialize, Serialize};

/// First Levenberg-style shift μ tried when `JᵀWJ` is not positive definite (relative to
/// `diag(JᵀWJ)`).
const SHIFT_START: f64 = 1e-12;
/// Largest shift tried: beyond it the matrix has non-finite entries.
const SHIFT_MAX: f64 = 1e16;

/// Damped Gauss-Newton solver settings and state.
///
/// Defaults: sufficient-decrease constant `c₁ = 1e-4`, backtracking factor ½, minimum
/// step length `α_min = 1e-10` (Nocedal & Wright 2006, section 3.1).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GaussNewton {
    tol: Tolerances,
    c1: f64,
    factor: f64,
    alpha_min: f64,
    monitor: Monitor,
    accepted: u64,
    termination: Option<Termination>,
}

impl GaussNewton {
    /// A solver with the given tolerances and the default line-search settings.
    pub fn new(tol: Tolerances) -> Self {
        Self {
            tol,
            c1: 1e-4,
            factor: 0.5,
            alpha_min: 1e-10,
            monitor: Monitor::default(),
            accepted: 0,
            termination: None,
        }
    }

    /// Sets the sufficient-decrease (Armijo) constant c₁ (dimensionless, in (0, 1)).
    ///
    /// # Errors
    /// [`crate::Error::InvalidOption`] for c₁ outside (0, 1) or not finite.
    pub fn with_c1(mut self, c1: f64) -> crate::Result<Self> {
        self.c1 = open_unit("c1", c1)?;
        Ok(self)
    }

    /// Sets the backtracking factor by which α shrinks after a failed trial (in (0, 1)).
    ///
    /// # Errors
    /// [`crate::Error::InvalidOption`] for a factor outside (0, 1) or not finite.
    pub fn with_backtracking_factor(mut self, factor: f64) -> crate::Result<Self> {
        self.factor = open_unit("backtracking_factor", factor)?;
        Ok(self)
    }

    /// Sets the minimum step length α_min (> 0); below it the line search has failed.
    ///
    /// # Errors
    /// [`crate::Error::InvalidOption`] for α_min not positive and finite, or above 1.
    pub fn with_min_alpha(mut self, alpha_min: f64) -> crate::Result<Self> {
        if !(alpha_min.is_finite() && alpha_min > 0.0 && alpha_min <= 1.0) {
            return Err(crate::Error::InvalidOption {
                option: "min_alpha".into(),
                reason: format!("must be in (0, 1], got {alpha_min}"),
            });
        }
        self.alpha_min = alpha_min;
        Ok(self)
    }

    /// Why the solver stopped, once it has.
    pub fn termination(&self) -> Option<&Termination> {
        self.termination.as_ref()
    }

    /// The stopping tolerances.
    pub fn tolerances(&self) -> &Tolerances {
        &self.tol
    }

    fn stop(&mut self, t: Termination) {
        self.termination = Some(t);
    }
}

fn open_unit(option: &str, v: f64) -> crate::Result<f64> {
    if v.is_finite() && v > 0.0 && v < 1.0 {
        Ok(v)
    } else {
        Err(crate::Error::InvalidOption {
            option: option.into(),
            reason: format!("must be in (0, 1), got {v}"),
        })
    }
}

/// Solves `H δ = g` by Cholesky, shifted by `μ diag(H)` with μ = 0, 1e-12, 1e-11, … while
/// `H` is not positive definite. Returns δ and μ; `None` only for non-finite entries.
fn shifted_solve(h: &Gram, g: &DVector<f64>) -> Option<(DVector<f64>, f64)> {
    if let Some(delta) = h.solve(g) {
        return Some((delta, 0.0));
    }
    let dmax = h.diagonal().iter().copied().filter(|d| d.is_finite()).fold(0.0, f64::max);
    let fill = if dmax > 0.0 { dmax } else { 1.0 };
    let d = h.diagonal().map(|v| if v > 0.0 { v } else { fill });
    let mut mu = SHIFT_START;
    while mu <= SHIFT_MAX {
        if let Some(delta) = damped_solve(h, &d, mu, g) {
            return Some((delta, mu));
        }
        mu *= 10.0;
    }
    None
}

impl ReportsTermination for GaussNewton {
    fn termination(&self) -> Option<&Termination> {
        self.termination.as_ref()
    }
    fn accepted_iterations(&self) -> u64 {
        self.accepted
    }
}

impl<O: LeastSquares> Solver<O, LsState> for GaussNewton {
    fn name(&self) -> &str {
        "gn"
    }

    fn init(
        &mut self,
        problem: &mut Problem<O>,
        state: LsState,
    ) -> Result<(LsState, Option<KV>), argmin::core::Error> {
        self.accepted = 0;
        let (state, t) = init_state(problem, state, &self.tol, &mut self.monitor)?;
        self.termination = t;
        let kv = argmin::kv!("c1" => self.c1; "backtracking_factor" => self.factor; "min_alpha" => self.alpha_min;);
        Ok((state, Some(kv)))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LsState,
    ) -> Result<(LsState, Option<KV>), argmin::core::Error> {
        let (p, grad, jtj, cost) = take_point(&mut state, "gn")?;
        self.monitor.observe(&jtj);
        let jtr = -&grad;
        let keep = |state: LsState, p: DVector<f64>, grad, jtj| {
            state.param(p).cost(cost).gradient(grad).hessian(jtj)
        };

        // Parameters pressed against a bound held there (Bertsekas 1982; Kelley 1999, 5.5).
        let none = DVector::zeros(p.len());
        let found =
            super::active::held_step(problem, &p, &jtj, &jtr, &none, |h, g, _, _| shifted_solve(h, g))?;
        let Some(super::active::HeldStep { delta, aux: shift, held }) = found else {
            // Only non-finite entries defeat every shift.
            self.stop(Termination::NoDescent);
            let kv = argmin::kv!(
                "alpha" => 0.0; "shift" => f64::INFINITY; "held" => 0u64; "trials" => 0u64; "accepted" => false;
            );
            return Ok((keep(state, p, grad, jtj), Some(kv)));
        };
        let held = held as u64;
        let project = |problem: &mut Problem<O>, mut x: DVector<f64>| {
            problem.problem("project_count", |o| {
                o.project_trial(&p, &mut x);
                Ok(())
            })?;
            Ok::<_, argmin::core::Error>(x)
        };
        // Decrease of the quadratic model along a step.
        let predicted = |step: &DVector<f64>| step.dot(&jtr) - 0.5 * step.dot(&jtj.mul(step));

        let full = project(problem, &p + &delta)?;
        let mut alpha = 1.0;
        let mut trials = 0u64;
        let mut trial = full;
        loop {
            trials += 1;
            let step = &trial - &p;
            let c = problem.problem("cost_count", |o| match o.cost(&trial) {
                Ok(c) => Ok(Some(c)),
                Err(e) if is_infeasible(&e) => Ok(None),
                Err(e) => Err(e.into()),
            })?;
            let armijo = cost - self.c1 * jtr.dot(&step);
            if let Some(c) = c.filter(|c| c.is_finite() && *c < cost && *c <= armijo) {
                // Whether the run ends here, by this search's cost (the normal equations'
                // agrees to rounding).
                let last =
                    Monitor::cost_converged(&self.tol, &Monitor::reductions(cost, Some(c), predicted(&step)))
                        || (trials == 1
                            && self.monitor.likely_last(&self.tol, &step, &trial, predicted(&step) / cost));
                let evaluate: fn(&O, &DVector<f64>) -> crate::Result<NormalEquations> =
                    if last { O::normal_equations_likely_last } else { O::normal_equations };
                let ne = trial_normal_equations(problem, &trial, |o, p| evaluate(o, p).map(Some))?;
                // The two evaluations agree to rounding; the state keeps the normal
                // equations' cost, which must also be a decrease.
                if let Some(ne) = ne.filter(|ne| ne.cost.is_finite() && ne.cost < cost) {
                    self.accepted += 1;
                    self.monitor.observe(&ne.jtj);
                    self.monitor.accept_step(&step);
                    let r = Monitor::reductions(cost, Some(ne.cost), predicted(&step));
                    if self.monitor.zero_residual(ne.cost) {
                        self.stop(Termination::ZeroResidual);
                    } else if Monitor::cost_converged(&self.tol, &r) {
                        self.stop(self.monitor.certify(Termination::CostTolerance, &ne.jtj, ne.cost));
                    } else if trials == 1 && self.monitor.small_step(&self.tol, &step, &trial) {
                        self.stop(self.monitor.certify(Termination::StepTolerance, &ne.jtj, ne.cost));
                    } else if Monitor::gradient_converged(&self.tol, &ne.jtj, &ne.jtr, ne.cost) {
                        self.stop(self.monitor.certify(Termination::GradientTolerance, &ne.jtj, ne.cost));
                    }
                    let kv = argmin::kv!(
                        "alpha" => alpha; "shift" => shift; "held" => held; "trials" => trials;
                        "accepted" => true; "cost_search" => c;
                    );
                    let gradient = ne.gradient();
                    return Ok((
                        state.param(trial).cost(ne.cost).gradient(gradient).hessian(ne.jtj),
                        Some(kv),
                    ));
                }
            }
            if trials == 1 && self.monitor.small_step(&self.tol, &step, &p) {
                // A full step below xtol that fails: backtracking cannot resolve more.
                self.stop(self.monitor.certify(Termination::StepTolerance, &jtj, cost));
                break;
            }
            if trials == 1
                && Monitor::cost_converged(&self.tol, &Monitor::reductions(cost, c, predicted(&step)))
            {
                // Even the full step cannot lower the cost by more than ftol: the cost is
                // at its rounding floor and backtracking would only chase rounding noise.
                self.stop(self.monitor.certify(Termination::CostTolerance, &jtj, cost));
                break;
            }
            alpha *= self.factor;
            if alpha < self.alpha_min {
                self.stop(Termination::NoDescent);
                break;
            }
            trial = project(problem, &p + &delta * alpha)?;
        }
        let kv = argmin::kv!(
            "alpha" => alpha; "shift" => shift; "held" => held; "trials" => trials; "accepted" => false;
        );
        Ok((keep(state, p, grad, jtj), Some(kv)))
    }

    fn terminate(&mut self, _state: &LsState) -> TerminationStatus {
        status(self.termination.as_ref())
    }
}
