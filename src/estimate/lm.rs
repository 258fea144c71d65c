//! Levenberg-Marquardt as an argmin [`Solver`].
//!
//! Each iteration solves `(JᵀWJ + λ D) δ = JᵀWε` by Cholesky (no inverse), with `D` the
//! running maximum of `diag(JᵀWJ)` (Moré 1978), projects `p + δ` on the bounds and
//! evaluates the trial point. The step is accepted only if the cost decreases; λ then
//! follows the gain ratio `ρ = ΔV_actual / ΔV_predicted` as `λ ← λ max(1/3, 1 − (2ρ − 1)³)`,
//! otherwise `λ ← ν λ`, `ν ← 2ν` (Nielsen 1999; Madsen, Nielsen & Tingleff, *Methods for
//! non-linear least squares problems*, 2004, section 3.2). Trial points where the model
//! cannot be simulated count as a rejected step.

use crate::estimate::solver::{
    LeastSquares, ReportsTermination, Termination, Tolerances, damped_solve, init_state, is_infeasible,
    scaled_gradient, status,
};
use argmin::core::{IterState, KV, Problem, Solver, TerminationStatus};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// argmin state used by the greybox solvers: parameter `p`, gradient `JᵀWε`, "Hessian" `JᵀWJ`.
pub type LsState = IterState<DVector<f64>, DVector<f64>, (), DMatrix<f64>, (), f64>;

/// Levenberg-Marquardt solver state and settings.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LevenbergMarquardt {
    tol: Tolerances,
    lambda: f64,
    nu: f64,
    diag: Option<DVector<f64>>,
    termination: Option<Termination>,
}

impl LevenbergMarquardt {
    /// A solver with the given tolerances and initial damping `λ₀ = 1e-3` (relative to
    /// `diag(JᵀWJ)`).
    pub fn new(tol: Tolerances) -> Self {
        Self { tol, lambda: 1e-3, nu: 2.0, diag: None, termination: None }
    }
    /// Sets the initial damping λ₀ (> 0).
    ///
    /// # Errors
    /// [`crate::Error::InvalidOption`] for λ₀ not positive and finite.
    pub fn with_lambda(mut self, lambda0: f64) -> crate::Result<Self> {
        if !(lambda0.is_finite() && lambda0 > 0.0) {
            return Err(crate::Error::InvalidOption {
                option: "lambda".into(),
                reason: format!("must be > 0, got {lambda0}"),
            });
        }
        self.lambda = lambda0;
        Ok(self)
    }
    /// Why the solver stopped, once it has.
    pub fn termination(&self) -> Option<&Termination> {
        self.termination.as_ref()
    }
    /// Current damping λ.
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    fn stop(&mut self, t: Termination) {
        self.termination = Some(t);
    }
}

impl<O: LeastSquares> Solver<O, LsState> for LevenbergMarquardt {
    fn name(&self) -> &str {
        "lm"
    }

    fn init(
        &mut self,
        problem: &mut Problem<O>,
        state: LsState,
    ) -> Result<(LsState, Option<KV>), argmin::core::Error> {
        let (state, t) = init_state(problem, state, &self.tol)?;
        self.termination = t;
        self.diag = state.get_hessian().map(|h| h.diagonal());
        Ok((state, Some(argmin::kv!("lambda" => self.lambda;))))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LsState,
    ) -> Result<(LsState, Option<KV>), argmin::core::Error> {
        let p = state.take_param().expect("initialised in init");
        let jtr = state.take_gradient().expect("initialised in init");
        let jtj = state.take_hessian().expect("initialised in init");
        let cost = state.get_cost();
        let d = self.diag.get_or_insert_with(|| jtj.diagonal());
        for j in 0..d.len() {
            d[j] = d[j].max(jtj[(j, j)]);
            if d[j] <= 0.0 {
                d[j] = 1.0;
            }
        }
        let restore = |state: LsState, jtr, jtj| state.param(p.clone()).cost(cost).gradient(jtr).hessian(jtj);

        let Some(delta) = damped_solve(&jtj, d, self.lambda, &jtr) else {
            self.lambda *= self.nu;
            self.nu *= 2.0;
            return Ok((
                restore(state, jtr, jtj),
                Some(argmin::kv!("lambda" => self.lambda; "accepted" => false;)),
            ));
        };
        let mut trial = &p + &delta;
        problem.problem("project_count", |o| {
            o.project(&mut trial);
            Ok(())
        })?;
        let step = &trial - &p;
        if step.norm() <= self.tol.xtol * (p.norm() + self.tol.xtol) {
            self.stop(Termination::StepTolerance);
            return Ok((
                restore(state, jtr, jtj),
                Some(argmin::kv!("lambda" => self.lambda; "accepted" => false;)),
            ));
        }
        let eval = problem.problem("normal_equations_count", |o| match o.normal_equations(&trial) {
            Ok(ne) => Ok(Some(ne)),
            Err(e) if is_infeasible(&e) => Ok(None),
            Err(e) => Err(e.into()),
        })?;
        let predicted = step.dot(&jtr) - 0.5 * step.dot(&(&jtj * &step));
        match eval {
            Some(ne) if ne.cost.is_finite() && ne.cost < cost => {
                let actual = cost - ne.cost;
                let rho = if predicted > 0.0 { actual / predicted } else { 1.0 };
                self.lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                self.lambda = self.lambda.max(1e-300);
                self.nu = 2.0;
                if ne.cost == 0.0 {
                    self.stop(Termination::ZeroResidual);
                } else if actual <= self.tol.ftol * cost {
                    self.stop(Termination::CostTolerance);
                } else if scaled_gradient(&ne.jtj, &ne.jtr, ne.cost) <= self.tol.gtol {
                    self.stop(Termination::GradientTolerance);
                }
                let kv = argmin::kv!("lambda" => self.lambda; "rho" => rho; "accepted" => true;);
                Ok((state.param(trial).cost(ne.cost).gradient(ne.jtr).hessian(ne.jtj), Some(kv)))
            }
            _ => {
                self.lambda *= self.nu;
                self.nu *= 2.0;
                if !self.lambda.is_finite() || self.lambda > 1e32 {
                    self.stop(Termination::NoDescent);
                }
                Ok((
                    restore(state, jtr, jtj),
                    Some(argmin::kv!("lambda" => self.lambda; "accepted" => false;)),
                ))
            }
        }
    }

    fn terminate(&mut self, _state: &LsState) -> TerminationStatus {
        status(self.termination.as_ref())
    }
}

impl ReportsTermination for LevenbergMarquardt {
    fn termination(&self) -> Option<&Termination> {
        self.termination.as_ref()
    }
}
