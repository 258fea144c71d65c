//! Reports apart from estimation (the goodness-of-fit metrics are the estimator's:
//! [`crate::estimate::metrics`]): comparisons of a model with data it was not fitted on (MATLAB's
//! `compare`), and the fit report as text or Markdown (engineering prefixes, aligned
//! columns).

pub mod compare;
pub mod eng;
#[cfg(feature = "plot")]
pub mod plot;
pub mod residuals;
pub mod summary;
pub mod text;

pub use compare::{Comparison, compare, compare_from, compare_predicted};
pub use text::{Align, Block, Document, Table};
