//! Levenberg-Marquardt with MINPACK's trust region (`lmder`; Moré, "The Levenberg-Marquardt
//! algorithm: implementation and theory", *Numerical Analysis*, LNM 630, 1978; Moré,
//! Garbow & Hillstrom, *User guide for MINPACK-1*, ANL-80-74, 1980) as an argmin [`Solver`].
//!
//! Where [`super::lm::LevenbergMarquardt`] damps by a λ that follows the gain ratio
//! (Nielsen) and never reaches 0, this solver bounds the step by a radius Δ in the D-scaled
//! norm and finds the λ that meets it (`lmpar`): a Gauss-Newton step inside the region is
//! taken undamped, which is what converges fast along a curved valley and at a zero
//! residual. Per trial step (one iteration, one evaluation):
//!
//! - the step `δ` of radius Δ (`lmpar`, warm-started at the last λ), with the parameters
//!   pressed against a bound held (the `active` module) and the trial point projected on
//!   the bounds, as Levenberg-Marquardt does; on the first iterations Δ is cut to `‖δ‖_D`;
//! - the gain ratio `ρ = actred/prered` (the `stopping` module's relative reductions);
//!   `ρ ≤ 0.25`: `Δ ← μ min(Δ, 10‖δ‖_D)`, `λ ← λ/μ` with `μ = ½`, or
//!   `½ dirder/(dirder + ½ actred)` for a cost that rose, at least 0.1 (0.1 for a cost that
//!   rose a hundredfold, tenfold in ‖ε‖), `dirder = −(δᵀJᵀWJδ + λ‖δ‖²_D)/(2V)`; `ρ ≥ 0.75`
//!   or `λ = 0`: `Δ ← 2‖δ‖_D`, `λ ← λ/2`;
//! - the step is taken where `ρ ≥ 1e-4` and the cost fell. A step cut by a bound
//!   (projected) can have a predicted reduction ≤ 0, which MINPACK's unbounded steps never
//!   have: it counts as a poor step (`ρ = 0`), taken only if the cost fell;
//! - MINPACK's tests after every trial: `ftol` on the relative reductions (`stopping`),
//!   `xtol` as `Δ ≤ xtol ‖p‖_D`, `gtol` at every new point; Δ below `ε_mach ‖p‖_D`
//!   ends the run as [`Termination::NoDescent`] (MINPACK's `info = 7`).
//!
//! Where the problem gives the square root of its normal equations
//! ([`LeastSquares::root`], asked once per point taken), the steps are MINPACK's on J's QR
//! factors (the `qrpar` module: column pivoting, `qrsolv`'s Givens rotations, the
//! Gauss-Newton step of the leading nonsingular columns of a rank-deficient J) and the
//! predicted reduction of a step that solved the damped system (no bound held, none hit) is
//! MINPACK's `½‖Rδ‖² + λ‖δ‖²_D`, a sum of non-negative terms: `δᵀJᵀWε − ½δᵀJᵀWJδ` cancels to
//! rounding noise where both terms are far above their difference (a plateau such as
//! Brown's almost-linear function at S = 1), and the `ftol` test would pass on that noise.
//! Otherwise the steps solve the normal equations (the `lmpar` module), whose condition
//! number is J's squared: near a zero residual whose Jacobian is singular (Powell's singular
//! function) the steps then lose their accuracy once JᵀWJ is singular to working precision,
//! and a row of J below `√ε_mach` of the others is lost in JᵀWJ.
//!
//! Δ₀ = 100 `‖p₀‖_D` (100 at p₀ = 0), MINPACK's `factor`; D as in the `stopping` module.
//! A trial whose cost passes 100 times the current one is abandoned there
//! ([`LeastSquares::normal_equations_below`]): MINPACK's `actred = −1` needs no more.
//!
//! KV per iteration: `radius`, `lambda`, `rho`, `actred`, `prered`, `held`, `accepted`.

use super::LsState;
use super::{
    Gram, LeastSquares, Monitor, ReportsTermination, Root, Termination, Tolerances, active, init_state,
    lmpar::lmpar, missing, qrpar::lmpar_qr, root::enorm, status, take_point, trial_normal_equations,
};
use argmin::core::{KV, Problem, Solver, State, TerminationStatus};
use serde::{Deserialize, Serialize};

/// MINPACK's `factor`: Δ₀ = `FACTOR ‖p₀‖_D`.
const FACTOR: f64 = 100.0;

/// Smallest gain ratio of a step taken (MINPACK's `1e-4`).
const MIN_RATIO: f64 = 1e-4;

/// Levenberg-Marquardt with MINPACK's trust region (Moré, "The Levenberg-Marquardt
/// algorithm: implementation and theory", LNM 630, 1978; MINPACK's `lmder`): each step is
/// the damped Gauss-Newton step `(JᵀWJ + λD)δ = JᵀWε` whose D-scaled length meets the
/// radius Δ (λ = 0 where the Gauss-Newton step lies inside it); Δ shrinks after a step
/// whose gain ratio ρ is at most 0.25 and becomes `2‖δ‖_D` after one above 0.75; a step is
/// taken where ρ ≥ 1e-4 and the cost fell. Stopping tests: [`Tolerances`] (MINPACK's
/// `ftol`, `xtol` as `Δ ≤ xtol ‖p‖_D`, `gtol`). On J's QR factors where the problem gives
/// them ([`LeastSquares::root`]), on JᵀWJ otherwise: see the
/// crate's `docs/performance.md` for where that differs from MINPACK. Used by
/// [`SolverKind::TrustRegion`](super::run::SolverKind::TrustRegion).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrustRegion {
    tol: Tolerances,
    /// Radius Δ in the D-scaled norm.
    radius: f64,
    /// The damping λ that met Δ at the last step (MINPACK's `par`).
    lambda: f64,
    /// `‖p‖_D` of the current point, with the scaling of when it was reached.
    xnorm: f64,
    monitor: Monitor,
    /// The square root of the normal equations at the current point, where the problem
    /// gives one ([`LeastSquares::root`]).
    #[serde(skip)]
    root: Option<Root>,
    /// Whether `root` is the current point's (false: ask at the next step).
    #[serde(skip)]
    root_current: bool,
    /// Whether the problem gave no root (asked no more).
    rootless: bool,
    /// MINPACK's `gnorm` at the current point from its root ([`Root::gnorm`]).
    #[serde(skip)]
    gnorm: Option<f64>,
    accepted: u64,
    termination: Option<Termination>,
}

impl TrustRegion {
    /// A solver with the given tolerances.
    pub fn new(tol: Tolerances) -> Self {
        Self {
            tol,
            radius: 0.0,
            lambda: 0.0,
            xnorm: 0.0,
            monitor: Monitor::default(),
            root: None,
            root_current: false,
            rootless: false,
            gnorm: None,
            accepted: 0,
            termination: None,
        }
    }
    /// Why the solver stopped, once it has.
    pub fn termination(&self) -> Option<&Termination> {
        self.termination.as_ref()
    }
    /// The current radius Δ (D-scaled norm of the scaled parameters).
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The radius and damping after a trial step of `D`-norm `pnorm` with gain ratio `rho`
    /// (0 for a step whose predicted reduction is not positive), actual relative reduction
    /// `actred`, `dirder` the directional derivative term and `rose_hundredfold` when the
    /// cost rose at least a hundredfold in V (tenfold in ‖ε‖).
    fn update_radius(&mut self, rho: f64, actred: f64, pnorm: f64, dirder: f64, rose_hundredfold: bool) {
        if rho <= 0.25 {
            let mut mu = if actred >= 0.0 { 0.5 } else { 0.5 * dirder / (dirder + 0.5 * actred) };
            if rose_hundredfold || mu.is_nan() || mu < 0.1 {
                mu = 0.1;
            }
            self.radius = mu * self.radius.min(pnorm / 0.1);
            self.lambda /= mu;
        } else if self.lambda == 0.0 || rho >= 0.75 {
            self.radius = pnorm / 0.5;
            self.lambda *= 0.5;
        }
    }
}

impl<O: LeastSquares> Solver<O, LsState> for TrustRegion {
    fn name(&self) -> &str {
        "trust-region"
    }

    fn init(
        &mut self,
        problem: &mut Problem<O>,
        state: LsState,
    ) -> Result<(LsState, Option<KV>), argmin::core::Error> {
        self.accepted = 0;
        self.lambda = 0.0;
        let (state, t) = init_state(problem, state, &self.tol, &mut self.monitor)?;
        self.termination = t;
        self.xnorm = state.get_param().map_or(0.0, |p| self.monitor.norm(p));
        self.radius = if self.xnorm > 0.0 { FACTOR * self.xnorm } else { FACTOR };
        (self.root, self.root_current, self.rootless, self.gnorm) = (None, false, false, None);
        Ok((state, Some(argmin::kv!("radius" => self.radius;))))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LsState,
    ) -> Result<(LsState, Option<KV>), argmin::core::Error> {
        let (p, grad, jtj, cost) = take_point(&mut state, "trust-region")?;
        let jtr = -&grad;
        if !self.root_current && !self.rootless {
            let root = root_at(problem, &p)?;
            self.rootless = root.is_none();
            // A non-finite root: this point's step on the normal equations.
            self.root = root.filter(Root::is_finite);
            self.root_current = true;
            // MINPACK's gtol test where it takes it, on the new point's factors.
            self.gnorm = self.root.as_ref().map(|r| r.gnorm((2.0 * cost).sqrt()));
            if self.gnorm.is_some_and(|g| g <= self.tol.gtol) {
                self.termination = Some(self.monitor.certify(Termination::GradientTolerance, &jtj, cost));
                return Ok((state.param(p).cost(cost).gradient(grad).hessian(jtj), None));
            }
        }

        let (radius, lambda) = (self.radius, self.lambda);
        let mut found = lambda;
        let root = self.root.as_ref().filter(|_| matches!(jtj, Gram::Dense(_)));
        let step = active::held_step(problem, &p, &jtj, &jtr, self.monitor.diag(), |h, g, d, free| {
            let (x, l) = match root {
                Some(root) => lmpar_qr(&root.pivoted(free), &d.map(f64::sqrt), radius, lambda)?,
                None => lmpar(h, g, d, radius, lambda)?,
            };
            found = l;
            Some((x, l))
        })?;
        let Some(active::HeldStep { delta: step, held, .. }) = step else {
            // No damped step is finite: JᵀWJ (or J's factors) not finite.
            self.termination = Some(Termination::NoDescent);
            return Ok((state.param(p).cost(cost).gradient(grad).hessian(jtj), None));
        };
        self.lambda = found;
        let mut trial = &p + &step;
        let unprojected = trial.clone();
        problem.problem("project_count", |o| {
            o.project_trial(&p, &mut trial);
            Ok(())
        })?;
        let projected = &trial - &p;
        let pnorm = self.monitor.norm(&projected);
        if self.accepted == 0 {
            self.radius = self.radius.min(pnorm);
        }
        // The step solved the damped system on J's factors: its predicted reduction is
        // MINPACK's sum of squares, free of the cancellation in δᵀJᵀWε − ½δᵀJᵀWJδ that
        // leaves rounding noise where both are near the cost's rounding.
        let exact = root.filter(|_| held == 0 && trial == unprojected);
        let (curvature, predicted) = match exact {
            Some(root) => {
                let jnorm = enorm(root.times(&step).iter().copied());
                let (curvature, norm) = (jnorm * jnorm, self.monitor.norm(&step));
                (curvature, 0.5 * curvature + self.lambda * norm * norm)
            }
            None => {
                let curvature = projected.dot(&jtj.mul(&projected));
                (curvature, projected.dot(&jtr) - 0.5 * curvature)
            }
        };
        let step = projected;
        let last = self.monitor.likely_last(&self.tol, &step, &trial, predicted / cost);
        let eval = trial_normal_equations(problem, &trial, |o, p| match last {
            true => o.normal_equations_likely_last(p).map(Some),
            false => o.normal_equations_below(p, 100.0 * cost),
        })?;
        let new_cost = eval.as_ref().map(|ne| ne.cost).filter(|c| c.is_finite());
        let r = Monitor::reductions(cost, new_cost, predicted);
        let dirder = -(curvature + self.lambda * pnorm * pnorm) / (2.0 * cost);
        let rho = if r.prered > 0.0 { r.ratio } else { 0.0 };
        self.update_radius(rho, r.actred, pnorm, dirder, new_cost.is_none_or(|c| c >= 100.0 * cost));
        let kv = |s: &Self, accepted: bool| {
            argmin::kv!(
                "radius" => s.radius; "lambda" => s.lambda; "rho" => r.ratio; "actred" => r.actred;
                "prered" => r.prered; "held" => held as u64; "accepted" => accepted;
            )
        };
        let taken = eval.filter(|ne| ne.cost < cost && (rho >= MIN_RATIO || r.prered <= 0.0));
        let (state, accepted) = match taken {
            Some(ne) => {
                self.accepted += 1;
                self.xnorm = self.monitor.norm(&trial);
                self.monitor.observe(&ne.jtj);
                self.monitor.accept_step(&step);
                self.root_current = false;
                if self.monitor.zero_residual(ne.cost) {
                    self.termination = Some(Termination::ZeroResidual);
                } else if Monitor::gradient_converged(&self.tol, &ne.jtj, &ne.jtr, ne.cost) {
                    self.termination =
                        Some(self.monitor.certify(Termination::GradientTolerance, &ne.jtj, ne.cost));
                }
                let gradient = ne.gradient();
                (state.param(trial).cost(ne.cost).gradient(gradient).hessian(ne.jtj), true)
            }
            None => (state.param(p).cost(cost).gradient(grad).hessian(jtj), false),
        };
        if self.termination.is_none() {
            let (h, c) =
                (state.get_hessian().ok_or_else(|| missing("trust-region", "JᵀWJ"))?, state.get_cost());
            let t = if Monitor::cost_converged(&self.tol, &r) {
                Some(Termination::CostTolerance)
            } else if self.radius <= self.tol.xtol * self.xnorm {
                Some(Termination::StepTolerance)
            } else if self.gnorm.is_some_and(|g| g <= f64::EPSILON) {
                // MINPACK's info 8 (reported by lmder1 as info 4): ε orthogonal to J's
                // columns to working precision at the point this trial started from; it
                // overrides info 7 below, as in lmder, where the last test that holds wins.
                Some(Termination::GradientTolerance)
            } else if self.radius <= f64::EPSILON * self.xnorm || self.radius.is_nan() || self.radius <= 0.0 {
                Some(Termination::NoDescent)
            } else {
                None
            };
            self.termination = t.map(|t| self.monitor.certify(t, h, c));
        }
        let kv = kv(self, accepted);
        Ok((state, Some(kv)))
    }

    fn terminate(&mut self, _state: &LsState) -> TerminationStatus {
        status(self.termination.as_ref())
    }
}

/// The problem's [`Root`] at `p`, counted as `root_count`; `None` where it gives none.
///
/// # Errors
/// Those of [`LeastSquares::root`]; [`crate::Error::Solver`] for a root whose shapes are
/// not those of p's n parameters ([`Root::check`]).
fn root_at<O: LeastSquares>(
    problem: &mut Problem<O>,
    p: &nalgebra::DVector<f64>,
) -> Result<Option<Root>, argmin::core::Error> {
    let root = problem.problem("root_count", |o| Ok(o.root(p)?))?;
    if let Some(root) = &root {
        root.check(p.len())?;
    }
    Ok(root)
}

impl ReportsTermination for TrustRegion {
    fn termination(&self) -> Option<&Termination> {
        self.termination.as_ref()
    }
    fn accepted_iterations(&self) -> u64 {
        self.accepted
    }
}
