//! How the solvers stop: their tolerances ([`Tolerances`]), the reason they stopped
//! ([`Termination`]) and what a run reports ([`SolverReport`]).

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Stopping tolerances shared by the solvers (MINPACK's `lmder`; Moré, Garbow & Hillstrom,
/// *User guide for MINPACK-1*, ANL-80-74, 1980; Moré 1978).
///
/// Norms are scaled by `D = diag(d_j)`, `d_j` the largest `‖J_j‖²` (column j of `√W J`)
/// met so far (1 for a column never non-zero): `‖x‖_D = √(Σ d_j x_j²)`, MINPACK's
/// `‖diag ∘ x‖` with its `mode = 1` scaling.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Tolerances {
    /// Stop when both the actual and the predicted relative reduction of the cost by a
    /// step are at most `ftol` (and the actual is at most twice the predicted).
    pub ftol: f64,
    /// Stop when a trial step δ satisfies `‖δ‖_D ≤ xtol ‖p‖_D` (p the point after it).
    pub xtol: f64,
    /// Stop when `max_j |J_jᵀWε| / (‖J_j‖ ‖√W ε‖) ≤ gtol` (cosine of residual and columns).
    pub gtol: f64,
    /// Maximum number of iterations (trial steps); by default 500, MINPACK's `lmder1`
    /// budget of `100 (n + 1)` evaluations for n = 4 parameters (Moré, Garbow & Hillstrom,
    /// ANL-80-74, 1980): a curve fit along a curved valley needs several hundred (NIST
    /// StRD's MGH09, MGH10 and MGH17 from their first starts, 278–495 with the trust region),
    /// a motor fit from the least-squares start 3–10.
    pub max_iters: u64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Self { ftol: 1e-12, xtol: 1e-10, gtol: 1e-10, max_iters: 500 }
    }
}

impl Tolerances {
    /// Largest accepted tolerance: a relative reduction, step or gradient cosine of 1 % or
    /// more is met before any progress, so the solver would "converge" where it started.
    pub const MAX: f64 = 1e-2;

    /// Checks that every tolerance is in `[0, MAX)` and `max_iters ≥ 1`.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming the tolerance.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("ftol", self.ftol), ("xtol", self.xtol), ("gtol", self.gtol)] {
            if !(v.is_finite() && (0.0..Self::MAX).contains(&v)) {
                return Err(Error::InvalidOption {
                    option: name.into(),
                    reason: format!(
                        "must be in [0, {:e}) (a larger relative tolerance is met before any progress), got {v}",
                        Self::MAX
                    ),
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
    /// The residual is zero to working precision: the cost at most `ε_mach² min(V₀, 1)`
    /// (`stopping::Monitor::zero_residual`), exactly zero included.
    ZeroResidual,
    /// `max_iters` reached before convergence.
    MaxIterations,
    /// No step along the search direction lowers the cost (line search failed).
    NoDescent,
    /// Every column of the Jacobian vanished (`‖J_j‖² ≤ ε_mach` × its largest value met)
    /// while the cost is far from zero (above `ε_mach V₀`): no step is defined and a
    /// convergence test passing there certifies nothing.
    ZeroJacobian,
    /// A linear problem solved in closed form (no iteration).
    ClosedForm,
    /// argmin stopped the run (timeout, interrupt, target cost).
    Stopped(String),
}

impl Termination {
    /// Whether the fit converged.
    pub fn success(&self) -> bool {
        matches!(
            self,
            Self::GradientTolerance
                | Self::StepTolerance
                | Self::CostTolerance
                | Self::ZeroResidual
                | Self::ClosedForm
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
            Self::ZeroJacobian => f.write_str("not converged: the Jacobian vanished at a non-zero residual"),
            Self::ClosedForm => f.write_str("solved in closed form (linear least squares)"),
            Self::Stopped(s) => write!(f, "not converged: stopped by the executor ({s})"),
        }
    }
}

/// A solver that records why it stopped and how many of its steps it accepted, so that
/// the fit report can say so.
pub trait ReportsTermination {
    /// Why the solver stopped, once it has; `None` while running or when argmin stopped it
    /// (iteration limit, timeout, interrupt).
    fn termination(&self) -> Option<&Termination>;
    /// Iterations whose step was accepted (the cost decreased); the others were rejected
    /// trial steps. Evaluations are counted apart, by argmin's function counts.
    fn accepted_iterations(&self) -> u64;
}

/// How the solver ran.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolverReport {
    /// `lm`, `gn` or `trust-region`.
    pub name: String,
    /// Iterations (trial steps).
    pub iterations: u64,
    /// Human-readable termination reason.
    pub termination: String,
    /// Machine-readable termination reason.
    pub reason: Termination,
    /// Whether the fit converged.
    pub success: bool,
    /// Cost and normal-equation evaluations.
    pub evaluations: u64,
    /// Iterations whose step was accepted (the cost decreased); `iterations` also counts
    /// rejected trial steps.
    #[serde(default)]
    pub accepted_iterations: u64,
    /// The solver's point p after each iteration, the start first (scaled space, each of
    /// length n_free; rows 1 + `iterations`). Not serialised: the fit report gives it in
    /// physical units ([`crate::estimate::FitResult::parameter_trace`]).
    #[serde(skip)]
    pub trace: Vec<Vec<f64>>,
}
