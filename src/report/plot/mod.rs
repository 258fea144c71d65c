//! SVG plots of a fit and of a comparison on a validation log (feature `plot`, with plotters' SVG backend; no fonts are needed: the viewer renders
//! the text).
//!
//! Every function takes data, never file names, and returns the SVG text; [`write_svg`]
//! writes it atomically ([`crate::data::write::write_atomic`]), so a failing plot leaves
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
//! observer ([`crate::online::plot`]).

pub(crate) mod draw;
mod fit;
mod time;
mod trend;

pub use fit::{compare_svg, fit_svg};
pub use trend::{MAX_NAMED_RUNS, Trend, TrendPoint, TrendSeries, trend_svg};

use crate::error::{Error, Result};
use std::path::Path;

/// A measured signal drawn above the outputs for context, e.g. the mechanical speed
/// `w_m` \[rad/s\]: its name, unit and samples per log (each as long as that log's
/// comparison).
#[derive(Clone, Copy, Debug)]
pub struct Context<'a> {
    /// Name shown on the axis, e.g. `w_m`.
    pub name: &'a str,
    /// Unit shown on the axis, e.g. `rad/s`.
    pub unit: &'a str,
    /// Samples of each log, in the order of the comparisons.
    pub per_log: &'a [&'a [f64]],
}

/// Writes `svg` to `path` atomically (a temporary file in the same folder, renamed over
/// the target).
///
/// # Errors
/// [`Error::Write`] naming the path when it cannot be written (missing folder, no
/// permission); no partial or temporary file is left.
pub fn write_svg(path: &Path, svg: &str) -> Result<()> {
    crate::data::write::write_atomic(path, |w| w.write_all(svg.as_bytes()))
}

/// At most `2 × columns` points `(t, y)` that draw like all of them at `columns` pixel
/// columns: the samples split into `columns` runs of consecutive samples, each
/// represented by its minimum and maximum in the order they occur (one point when they
/// coincide). Fewer samples than `2 × columns` are returned as they are; `columns = 0` or
/// lengths that disagree give no point. Non-finite values are skipped.
pub fn decimate_min_max(t: &[f64], y: &[f64], columns: usize) -> Vec<(f64, f64)> {
    let n = t.len().min(y.len());
    if columns == 0 || t.len() != y.len() {
        return Vec::new();
    }
    let finite = |k: &usize| y[*k].is_finite() && t[*k].is_finite();
    if n <= 2 * columns {
        return (0..n).filter(finite).map(|k| (t[k], y[k])).collect();
    }
    let mut out = Vec::with_capacity(2 * columns);
    for c in 0..columns {
        let (a, b) = (c * n / columns, (c + 1) * n / columns);
        let run = (a..b).filter(finite);
        let lo = run.clone().min_by(|&i, &j| y[i].total_cmp(&y[j]));
        let hi = run.max_by(|&i, &j| y[i].total_cmp(&y[j]));
        if let (Some(lo), Some(hi)) = (lo, hi) {
            let (first, second) = if lo <= hi { (lo, hi) } else { (hi, lo) };
            out.push((t[first], y[first]));
            if second != first {
                out.push((t[second], y[second]));
            }
        }
    }
    out
}

/// A drawing failure as the crate's error (option `plot`).
pub(crate) fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::InvalidOption { option: "plot".into(), reason: e.to_string() }
}

#[cfg(test)]
mod tests {
    use super::decimate_min_max;

    #[test]
    fn decimation_keeps_extremes_and_caps_points() {
        let t: Vec<f64> = (0..10_000).map(|k| k as f64).collect();
        let mut y: Vec<f64> = t.iter().map(|v| (v / 50.0).sin()).collect();
        y[1234] = 7.0;
        y[5678] = -9.0;
        let d = decimate_min_max(&t, &y, 100);
        assert!(d.len() <= 200);
        assert!(d.contains(&(1234.0, 7.0)) && d.contains(&(5678.0, -9.0)));
        assert!(d.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!(decimate_min_max(&t[..10], &y[..10], 100).len(), 10);
        assert!(decimate_min_max(&t, &y[..5], 100).is_empty());
    }
}
