//! What a solver needs from a least-squares problem ([`LeastSquares`]): its normal
//! equations and cost at a point, and the argmin state the solvers share ([`LsState`]).

use super::{Gram, Root};
use crate::error::{Error, Result};
use argmin::core::IterState;
use nalgebra::DVector;

/// argmin state of the greybox solvers: parameter `p` (scaled space, length n_free), gradient
/// `∇V = −JᵀWε` (length n_free), "Hessian" `JᵀWJ` (n_free × n_free, [`Gram`]), cost `V`.
pub type LsState = IterState<DVector<f64>, DVector<f64>, (), Gram, (), f64>;

/// Cost and normal equations at one point (scaled space, length n_free).
#[derive(Clone, Debug)]
pub struct NormalEquations {
    /// `V = Σ w ρ(ε)` (`½ εᵀWε` for the quadratic loss).
    pub cost: f64,
    /// `JᵀWJ` (IRLS-weighted for a robust loss), `n_free × n_free`: dense, or by the blocks
    /// of its arrowhead structure.
    pub jtj: Gram,
    /// `JᵀWψ(ε)` (`JᵀWε` for the quadratic loss), length n_free: the negative gradient `−∇V`.
    pub jtr: DVector<f64>,
}

impl NormalEquations {
    /// Gradient of the cost `∇V = −JᵀWψ(ε)`, length n_free.
    pub fn gradient(&self) -> DVector<f64> {
        -&self.jtr
    }
}

/// A nonlinear least-squares problem in scaled variables p, as the solvers see it.
pub trait LeastSquares {
    /// Number of free parameters n_free.
    fn n_params(&self) -> usize;
    /// Cost `V(p) = ½ εᵀWε` with `JᵀWJ` and `JᵀWε` (`J = ∂ŷ/∂p`, `ε = y − ŷ`).
    ///
    /// # Errors
    /// [`Error::SimulationDiverged`] or [`Error::InvalidParameter`] at a point the model
    /// cannot simulate (the solvers treat these as an infinite cost at trial points);
    /// anything else aborts the fit.
    fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations>;
    /// [`normal_equations`](Self::normal_equations) at a trial point that, once accepted,
    /// likely ends the run: its step already passes the step test, the cost reduction its
    /// quadratic model predicts passes the cost test, or the step after it, extrapolated
    /// from the last two, would pass the step test. The solvers ask this of such points, so that a problem may gather in
    /// the same pass what its statistics need at the estimate and spare a pass after the
    /// run ([`PemProblem`](crate::estimate::PemProblem) keeps the residuals' lag sums).
    /// The returned normal equations are those of `normal_equations(p)` to the bit; by
    /// default this is `normal_equations(p)`.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    fn normal_equations_likely_last(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        self.normal_equations(p)
    }
    /// [`normal_equations`](Self::normal_equations) at a trial point that is of use only
    /// if its cost is below `bound` (the current point's, which a step must lower):
    /// `Ok(None)` once a partial sum of the cost already exceeds `bound`, so the step would
    /// be rejected whatever the rest of the pass gives, sparing that rest. Every `Some`
    /// holds the normal equations of `normal_equations(p)` to the bit. By default this
    /// never abandons a pass.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    fn normal_equations_below(&self, p: &DVector<f64>, bound: f64) -> Result<Option<NormalEquations>> {
        let _ = bound;
        self.normal_equations(p).map(Some)
    }
    /// Cost `V(p)` alone.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    fn cost(&self, p: &DVector<f64>) -> Result<f64>;
    /// `JᵀWε(q)`, length n_free: the residual at `q` weighted by the Jacobian at `p`, for
    /// the geodesic acceleration of Levenberg-Marquardt (the `geodesic` module), which
    /// takes the second directional derivative of the residual along a step from it.
    /// Contract: at `q = p` it is `normal_equations(p).jtr` (up to rounding), with the same
    /// weights, filters and parameters; the solver divides its difference from that by
    /// `h² / 2 = 0.005`, so any other difference is magnified 200 times. `Ok(None)`: the
    /// problem does not provide it (the default), and the solver takes the plain step.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations), at `p` or `q`.
    fn directional_gradient(&self, p: &DVector<f64>, q: &DVector<f64>) -> Result<Option<DVector<f64>>> {
        let _ = (p, q);
        Ok(None)
    }
    /// The square root of the normal equations at `p` ([`Root`]: `√W J = Q R`, with
    /// `RᵀR = JᵀWJ` and `Rᵀ qtf = JᵀWε` of [`normal_equations`](Self::normal_equations)
    /// up to rounding), for the trust region's steps on J's QR factors, which keep J's
    /// condition number where the normal equations square it (the `qrpar` module).
    /// `Ok(None)`: the problem does not keep J (the default), and the trust region solves
    /// the normal equations.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    fn root(&self, p: &DVector<f64>) -> Result<Option<Root>> {
        let _ = p;
        Ok(None)
    }
    /// Whether [`root`](Self::root) gives a root wherever the model can be evaluated (the
    /// problem keeps J); [`SolverKind::Auto`](super::run::SolverKind::Auto) then runs the
    /// trust region. By default false.
    fn keeps_root(&self) -> bool {
        false
    }
    /// Projects p onto the feasible box in place.
    fn project(&self, p: &mut DVector<f64>);
    /// Projects the trial point `p`, a step from the current point `from` (inside the
    /// box), onto the feasible box; a parameter whose lower bound is strictly positive (a
    /// positivity constraint) and which the step takes past zero is put at
    /// a hundredth (`POSITIVE_FLOOR`) of its value at `from` first: the fraction-to-the-boundary rule
    /// of interior-point methods (Wächter & Biegler 2006, "On the implementation of an
    /// interior-point filter line-search algorithm for large-scale nonlinear
    /// programming", Math. Program. 106(1), eq. (15), τ = 0.99; Nocedal & Wright,
    /// *Numerical Optimization*, 2006, eq. (19.9)) for the steps that leave the positive
    /// half-line, so that such a trial is tried at a hundredth of the value, not at a bound
    /// such as 1e-12 of it where the model may be absurd and slow to simulate. A step that
    /// stays positive is projected as by [`project`](Self::project), which this is by
    /// default; a problem may leave out parameters whose bound can be their answer
    /// ([`crate::estimate::PemProblem`] leaves out nuisance parameters).
    fn project_trial(&self, from: &DVector<f64>, p: &mut DVector<f64>) {
        let _ = from;
        self.project(p)
    }
}

/// The fraction of its current value at which a trial puts a parameter with a strictly
/// positive lower bound that the step takes past zero ([`LeastSquares::project_trial`];
/// IPOPT's `1 − τ_min`).
pub(crate) const POSITIVE_FLOOR: f64 = 0.01;

impl<T: LeastSquares + ?Sized> LeastSquares for &T {
    fn n_params(&self) -> usize {
        (**self).n_params()
    }
    fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        (**self).normal_equations(p)
    }
    fn normal_equations_likely_last(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        (**self).normal_equations_likely_last(p)
    }
    fn normal_equations_below(&self, p: &DVector<f64>, bound: f64) -> Result<Option<NormalEquations>> {
        (**self).normal_equations_below(p, bound)
    }
    fn cost(&self, p: &DVector<f64>) -> Result<f64> {
        (**self).cost(p)
    }
    fn directional_gradient(&self, p: &DVector<f64>, q: &DVector<f64>) -> Result<Option<DVector<f64>>> {
        (**self).directional_gradient(p, q)
    }
    fn root(&self, p: &DVector<f64>) -> Result<Option<Root>> {
        (**self).root(p)
    }
    fn keeps_root(&self) -> bool {
        (**self).keeps_root()
    }
    fn project(&self, p: &mut DVector<f64>) {
        (**self).project(p)
    }
    fn project_trial(&self, from: &DVector<f64>, p: &mut DVector<f64>) {
        (**self).project_trial(from, p)
    }
}

/// Whether an evaluation error only means "this trial point is unusable".
pub(crate) fn is_infeasible(e: &Error) -> bool {
    matches!(e, Error::SimulationDiverged { .. } | Error::InvalidParameter { .. })
}

/// The normal equations at a trial point by `evaluate` (the problem's `normal_equations`,
/// `normal_equations_likely_last` for a trial expected to end the run, or
/// `normal_equations_below` the current cost), counted as argmin counts them; `None` where
/// the model cannot be simulated there ([`is_infeasible`]) or `evaluate` abandoned the pass.
///
/// # Errors
/// Every other error of `evaluate`.
pub(crate) fn trial_normal_equations<O: LeastSquares>(
    problem: &mut argmin::core::Problem<O>,
    trial: &DVector<f64>,
    evaluate: impl FnOnce(&O, &DVector<f64>) -> Result<Option<NormalEquations>>,
) -> std::result::Result<Option<NormalEquations>, argmin::core::Error> {
    problem.problem("normal_equations_count", |o| match evaluate(o, trial) {
        Ok(ne) => Ok(ne),
        Err(e) if is_infeasible(&e) => Ok(None),
        Err(e) => Err(e.into()),
    })
}
