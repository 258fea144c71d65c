//! Reports apart from estimation: goodness-of-fit metrics as functions of measured and
//! simulated outputs, usable on data the fit did not see (MATLAB's `compare`).

pub mod metrics;

pub use metrics::{Metrics, Whiteness, metrics};
