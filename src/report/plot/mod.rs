//! SVG plots of a fit and of a comparison on a validation log (feature `plot`, with plotters' SVG backend; no fonts are needed: the viewer renders
//! the text).
//!
//! Every function takes data, never file names, and returns the SVG text; [`write_svg`]
//! writes it atomically ([`crate::data::write_atomic`]), so a failing plot leaves
//! neither a partial file nor a temporary one. Long signals are decimated for drawing only
//! ([`decimate_min_max`]: the minimum and maximum of each pixel column), never for fitting.
//!
//! - [`fit_svg`]: measured and simulated outputs over time with a context signal (the
//!   speed), residuals with their ±2σ band, residual autocorrelation with its 95 % bound,
//!   the parameter trace over the iterations, the estimates with their 95 % intervals;
//! - [`compare_svg`]: the same time panels and autocorrelation for a model on logs it was
//!   not fitted on (MATLAB's `compare`; Ljung, *System Identification*, 16.5–16.6);
//! - [`trend_svg`]: estimates over a sequence of runs (one fit per log) with their 95 %
//!   intervals as error bars.
//!
//! The drawing helpers (module `draw`) also serve the observer's plot, which lives with the
//! observer ([`crate::online::track_svg`]).

mod context;
mod decimate;
pub(crate) mod draw;
mod fit;
mod svg;
mod time;
mod trend;

pub use context::Context;
pub use decimate::decimate_min_max;
pub use fit::{compare_svg, fit_svg};
pub(crate) use svg::plot_error;
pub use svg::write_svg;
pub use trend::{MAX_NAMED_RUNS, Trend, TrendPoint, TrendSeries, trend_svg};
