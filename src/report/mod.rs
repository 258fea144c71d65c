//! Reports apart from estimation (the goodness-of-fit metrics are the estimator's:
//! [`crate::estimate::Metrics`]): comparisons of a model with data it was not fitted on (MATLAB's
//! `compare`), and the fit report as text or Markdown (engineering prefixes, aligned
//! columns).

// The submodules are the crate's, their public items re-exported here (one path each);
// the plots are a folder of their own.
pub(crate) mod compare;
pub(crate) mod eng;
#[cfg(feature = "plot")]
pub mod plot;
pub(crate) mod residuals;
pub(crate) mod summary;
pub(crate) mod text;

pub use compare::{Comparison, compare, compare_from, compare_predicted};
pub use eng::{UnitScale, decimals_for, display_unit, format_eng, format_figure, prefix_exponent};
pub use residuals::write_residuals_csv;
pub use summary::{ERROR_INDEX_LEGEND, NO_ERROR_INDEX, REMARKS, estimate_cells, label};
pub use text::{Align, Block, Document, Table};
