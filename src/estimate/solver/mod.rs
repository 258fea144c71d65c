//! Nonlinear least-squares solvers as argmin [`Solver`](argmin::core::Solver)s: what they
//! need from a problem ([`LeastSquares`]), their tolerances, how they stop, and how a fit
//! runs them ([`run::run_solver`]).
//!
//! This folder knows nothing of models, simulation or the prediction-error problem: the
//! problem implements [`LeastSquares`] (`estimate::problem` imports this module, never the
//! reverse), so any least-squares problem (a curve fit, the Moré-Garbow-Hillstrom test
//! set) runs through the same code as a motor fit.
//!
//! Sign convention: `J = ∂ŷ/∂p` is the Jacobian of the model output and `ε = y − ŷ` the
//! residual, so the gradient of the cost `V = ½ εᵀWε` is `∇V = −JᵀWε`.
//! [`NormalEquations::jtr`] holds `JᵀWε` (the steepest-descent direction); argmin's
//! gradient slot of the solvers' state ([`LsState`]) holds `∇V`, as argmin documents it.

mod active;
mod geodesic;
pub(crate) mod gn;
mod gram;
pub(crate) mod lm;
mod lmpar;
mod problem;
mod qrpar;
mod root;
pub(crate) mod run;
mod stopping;
mod termination;
pub(crate) mod trust;

pub(crate) use stopping::{Monitor, damped_solve, init_state, missing, status, take_point};

pub use gram::Gram;
pub(crate) use problem::POSITIVE_FLOOR;
pub use problem::{LeastSquares, LsState, NormalEquations};
pub(crate) use problem::{is_infeasible, trial_normal_equations};
pub use root::Root;
pub use termination::{ReportsTermination, SolverReport, Termination, Tolerances};
