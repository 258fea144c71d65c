//! Reports apart from estimation: the goodness-of-fit metrics (defined beside the estimator
//! in [`crate::estimate::metrics`], re-exported here), comparisons of a model with data it was not fitted on (MATLAB's
//! `compare`), and the fit report as text or Markdown (engineering prefixes, aligned
//! columns).

pub mod compare;
pub mod eng;
#[cfg(feature = "plot")]
pub mod plot;
pub mod residuals;
pub mod summary;
pub mod text;

pub use crate::estimate::metrics::{self, Metrics, Whiteness, metrics};
pub use compare::{Comparison, compare, compare_from, compare_predicted};
pub use text::{Align, Block, Document, Table};
