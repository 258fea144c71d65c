//! The linear least-squares estimate on the voltage equations (thesis 5.2.1): the
//! regression, the start of the prediction-error fit, and its report.

mod least_squares;
mod regression;
pub(super) mod report;
pub(super) mod start;
mod steady;
mod steady_model;
mod steady_samples;
mod steady_solve;

pub use least_squares::*;
pub use regression::regressors;
pub(crate) use regression::{MAX_COLS, Regression, push_with_dead_time};
pub(crate) use steady::steady_state_of;
pub use steady::{
    PERIOD_TERM, SteadyEstimate, SteadyOptions, UNIDENTIFIABLE as STEADY_UNIDENTIFIABLE, steady_advice,
    steady_state,
};
