//! Levenberg-Marquardt as an argmin [`Solver`].
//!
//! Each iteration solves `(JᵀWJ + λ D) δ = −∇V = JᵀWε` by Cholesky (no inverse), with `D`
//! the running maximum of `diag(JᵀWJ)` (Moré 1978), with the parameters pressed against a
//! bound held there and the system solved for the others (KV `held`; the `active` module),
//! projects `p + δ` on the bounds (a parameter bounded above 0 that the step takes past
//! zero put at a hundredth of its value, [`LeastSquares::project_trial`]) and evaluates
//! the trial point. The step is accepted only
//! if the cost decreases; λ then follows the gain ratio `ρ = ΔV_actual / ΔV_predicted` as
//! `λ ← λ max(1/3, 1 − (2ρ − 1)³)`, otherwise `λ ← ν λ`, `ν ← 2ν` (Nielsen 1999; Madsen,
//! Nielsen & Tingleff, *Methods for non-linear least squares problems*, 2004, section
//! 3.2). Trial points where the model cannot be simulated count as a rejected step, and so
//! does a trial whose pass is abandoned once its running cost exceeds the current cost
//! ([`LeastSquares::normal_equations_below`]; the same path to the bit, without the rest of
//! such a pass).
//!
//! The damping differs from MINPACK's trust region; the stopping tests are MINPACK's
//! (`lmder`; see [`Tolerances`] and the `stopping` module): `ftol` on both the actual and
//! the predicted relative reduction of every accepted step, `xtol` on every trial step in
//! the D-scaled norm (after it is evaluated and, if it lowers the cost, taken: near a zero
//! residual that last step squares the residual) and on the step that the local model asks
//! for next from an accepted point (before it is evaluated: the run ends at that point,
//! which is within `xtol ‖p‖_D` of the one the step would reach; MINPACK bounds that next
//! step by its trust radius Δ and tests Δ), `gtol` on the scaled gradient at every
//! accepted point, and [`Termination::NoDescent`] when λ exceeds 1e32. One difference:
//! MINPACK also applies the `ftol` test after a rejected step; here a rejected step only
//! raises λ (see the comment in `next_iter`). A test passing where the Jacobian has
//! vanished at a cost far from zero gives [`Termination::ZeroJacobian`].
//!
//! With geodesic acceleration (the `geodesic` module; [`LevenbergMarquardt::with_geodesic`]),
//! a step with no parameter held at a bound is bent along the valley by its second-order
//! term `a/2` (Transtrum & Sethna 2012) where that term is small against the step.
//!
//! KV per iteration: `lambda`, `accepted`, and for evaluated steps `rho`, `actred`,
//! `prered`, `held`, `accelerated`.

pub use super::LsState;
use super::{
    LeastSquares, Monitor, ReportsTermination, Termination, Tolerances, active, damped_solve, geodesic,
    init_state, status, take_point, trial_normal_equations,
};
use argmin::core::{KV, Problem, Solver, TerminationStatus};
use nalgebra::DVector;
use serde::{Deserialize, Serialize};

/// λ₀ of a run from a start of unknown quality (Madsen, Nielsen & Tingleff 2004, 3.2).
pub const DEFAULT_DAMPING: f64 = 1e-3;

/// Damping beyond which no step can lower the cost.
const LAMBDA_MAX: f64 = 1e32;

/// Levenberg-Marquardt solver state and settings.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LevenbergMarquardt {
    tol: Tolerances,
    lambda: f64,
    nu: f64,
    monitor: Monitor,
    accepted: u64,
    termination: Option<Termination>,
    /// Geodesic acceleration on.
    #[serde(default)]
    geodesic: bool,
    /// Whether the last step was rejected or its gain ratio fell below
    /// [`geodesic::CURVED`]: the local linear model is poor, and the next step is
    /// accelerated.
    #[serde(default)]
    curved: bool,
}

impl LevenbergMarquardt {
    /// A solver with the given tolerances and initial damping
    /// `λ₀ =` [`DEFAULT_DAMPING`] (relative to `diag(JᵀWJ)`).
    pub fn new(tol: Tolerances) -> Self {
        Self {
            tol,
            lambda: DEFAULT_DAMPING,
            nu: 2.0,
            monitor: Monitor::default(),
            accepted: 0,
            termination: None,
            geodesic: false,
            curved: false,
        }
    }
    /// Geodesic acceleration on or off (off by default; Transtrum & Sethna,
    /// arXiv:1201.5885, 2012). On, each step after a rejected one or after a gain ratio
    /// below 0.75, with no parameter held at a bound, costs two more passes (the residuals
    /// at `p + 0.1 δ`, the Jacobian at `p`), counted as two evaluations; a problem without
    /// [`LeastSquares::directional_gradient`] takes plain steps. On MINPACK's test set it
    /// takes fewer steps in curved valleys and more evaluations on most problems
    /// (docs/performance.md), hence off by default.
    pub fn with_geodesic(mut self, geodesic: bool) -> Self {
        self.geodesic = geodesic;
        self
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

    /// A rejected step: more damping, [`Termination::NoDescent`] beyond [`LAMBDA_MAX`].
    fn reject(&mut self) {
        self.lambda *= self.nu;
        self.nu *= 2.0;
        if self.termination.is_none() && !(self.lambda.is_finite() && self.lambda <= LAMBDA_MAX) {
            self.stop(Termination::NoDescent);
        }
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
        self.accepted = 0;
        self.curved = false;
        let (state, t) = init_state(problem, state, &self.tol, &mut self.monitor)?;
        self.termination = t;
        Ok((state, Some(argmin::kv!("lambda" => self.lambda;))))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LsState,
    ) -> Result<(LsState, Option<KV>), argmin::core::Error> {
        let (p, grad, jtj, cost) = take_point(&mut state, "lm")?;
        self.monitor.observe(&jtj);
        let jtr = -&grad;
        let keep = |state: LsState, p: DVector<f64>, grad, jtj| {
            state.param(p).cost(cost).gradient(grad).hessian(jtj)
        };

        // Parameters pressed against a bound held there, the others' damped step solved
        // without them (`active`): projecting the unbounded step instead crawled along a
        // bound, its other components those of a move the bound forbids.
        let lambda = self.lambda;
        let step = active::held_step(problem, &p, &jtj, &jtr, self.monitor.diag(), |h, g, d, _| {
            damped_solve(h, d, lambda, g).map(|x| (x, 0.0))
        })?;
        let Some(active::HeldStep { delta, held, .. }) = step else {
            self.reject();
            let kv = argmin::kv!("lambda" => self.lambda; "accepted" => false;);
            return Ok((keep(state, p, grad, jtj), Some(kv)));
        };
        let bent = match self.geodesic && self.curved && held == 0 {
            true => geodesic::accelerated(problem, &p, &delta, (&jtj, &jtr), &self.monitor, lambda)?,
            false => None,
        };
        let accelerated = bent.is_some();
        let mut trial = &p + bent.as_ref().unwrap_or(&delta);
        problem.problem("project_count", |o| {
            o.project_trial(&p, &mut trial);
            Ok(())
        })?;
        let step = &trial - &p;
        let predicted = step.dot(&jtr) - 0.5 * step.dot(&jtj.mul(&step));
        // A trial that likely ends the run gathers what the statistics need; any other is
        // abandoned once its cost is known to exceed the current one (a rejected step
        // either way: far trials from a poor start, whose simulation may be slow, cost
        // only the part of the pass that shows it).
        let last = self.monitor.likely_last(&self.tol, &step, &trial, predicted / cost);
        let eval = trial_normal_equations(problem, &trial, |o, p| match last {
            true => o.normal_equations_likely_last(p).map(Some),
            false => o.normal_equations_below(p, cost),
        })?;
        let r = Monitor::reductions(cost, eval.as_ref().map(|ne| ne.cost), predicted);
        match eval {
            Some(ne) if ne.cost.is_finite() && ne.cost < cost => {
                self.accepted += 1;
                let rho = if r.prered > 0.0 { r.ratio } else { 1.0 };
                self.curved = rho < geodesic::CURVED;
                self.lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                self.lambda = self.lambda.max(1e-300);
                self.nu = 2.0;
                self.monitor.observe(&ne.jtj);
                self.monitor.accept_step(&step);
                if self.monitor.zero_residual(ne.cost) {
                    self.stop(Termination::ZeroResidual);
                } else if Monitor::cost_converged(&self.tol, &r) {
                    self.stop(self.monitor.certify(Termination::CostTolerance, &ne.jtj, ne.cost));
                } else if self.monitor.small_step(&self.tol, &step, &trial) {
                    self.stop(self.monitor.certify(Termination::StepTolerance, &ne.jtj, ne.cost));
                } else if Monitor::gradient_converged(&self.tol, &ne.jtj, &ne.jtr, ne.cost) {
                    self.stop(self.monitor.certify(Termination::GradientTolerance, &ne.jtj, ne.cost));
                } else if damped_solve(&ne.jtj, self.monitor.diag(), self.lambda, &ne.jtr).is_some_and(
                    |next| {
                        let predicted = next.dot(&ne.jtr) - 0.5 * next.dot(&ne.jtj.mul(&next));
                        self.monitor.small_step(&self.tol, &next, &trial)
                            && predicted <= self.tol.ftol * ne.cost
                    },
                ) {
                    // The next step would move the point by less than xtol and lower the
                    // cost by less than ftol, by the local model: the run ends here
                    // rather than spend a pass on it.
                    self.stop(self.monitor.certify(Termination::StepTolerance, &ne.jtj, ne.cost));
                }
                let kv = argmin::kv!(
                    "lambda" => self.lambda; "rho" => r.ratio; "actred" => r.actred; "prered" => r.prered;
                    "held" => held as u64; "accepted" => true; "accelerated" => accelerated;
                );
                let gradient = ne.gradient();
                Ok((state.param(trial).cost(ne.cost).gradient(gradient).hessian(ne.jtj), Some(kv)))
            }
            _ => {
                // MINPACK applies the ftol test here too. Nielsen's λ never reaches 0, so
                // near a flat valley the damped step understates what an undamped one
                // still gains in the parameters (Misra1a: 6e-9 short of the certified
                // values); a rejected step only raises λ, and xtol ends the run.
                if self.monitor.small_step(&self.tol, &step, &p) {
                    self.stop(self.monitor.certify(Termination::StepTolerance, &jtj, cost));
                }
                self.curved = true;
                self.reject();
                let kv = argmin::kv!(
                    "lambda" => self.lambda; "rho" => r.ratio; "actred" => r.actred; "prered" => r.prered;
                    "held" => held as u64; "accepted" => false; "accelerated" => accelerated;
                );
                Ok((keep(state, p, grad, jtj), Some(kv)))
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
    fn accepted_iterations(&self) -> u64 {
        self.accepted
    }
}
