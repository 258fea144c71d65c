//! Reports apart from estimation: goodness-of-fit metrics as functions of measured and
//! simulated outputs, and comparisons of a model with data it was not fitted on (MATLAB's
//! `compare`).

pub mod compare;
pub mod metrics;
#[cfg(feature = "plot")]
pub mod plot;
pub mod residuals;

pub use compare::{Comparison, compare, compare_from};
pub use metrics::{Metrics, Whiteness, metrics};
