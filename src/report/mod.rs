//! Reports apart from estimation: goodness-of-fit metrics as functions of measured and
//! simulated outputs, and comparisons of a model with data it was not fitted on (MATLAB's
//! `compare`).

pub mod compare;
pub mod metrics;

pub use compare::{Comparison, compare};
pub use metrics::{Metrics, Whiteness, metrics};
