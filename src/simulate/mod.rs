//! Simulation of a [`GreyBoxModel`](crate::model::GreyBoxModel): single shooting from the measured (or a given) first
//! state, with forward sensitivities, streamed sample by sample; one [`SimOptions`] says
//! how.
//!
//! [`simulate`] returns the predicted outputs; [`visit_sensitivities`] calls a closure with
//! `ŷ_k`, `∂ŷ_k/∂θ` and optionally `∂ŷ_k/∂x₀` at every sample, so that an estimator can accumulate the normal
//! equations `JᵀJ`, `Jᵀε` in one pass without ever storing the `N n_y × n_θ` Jacobian.
//! Models without analytic sensitivities get them from central finite differences of
//! their step (crate `finitediff`), with steps relative to each parameter's scale.
//!
//! Source: forward sensitivity analysis of a discrete recursion, e.g. Ljung, *System
//! Identification* (2nd ed.), section 10.3; thesis section 5.3 (Tenerz 2011).

mod blocks;
mod checks;
mod fd;
mod run;

pub use blocks::simulate_blocks;
pub use checks::SimOptions;
pub(crate) use checks::{check_inputs, check_shooting, diverged};
pub use run::{simulate, visit_sensitivities};
