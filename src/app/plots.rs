//! The fit and comparison plots as SVG text, with the speed of each log as context: what
//! `greybox fit --plot` and `validate --plot` write and Python's `Fit.plot` returns.

use crate::Experiment;
use crate::error::Result;
use crate::pmsm::{PmsmFit, channel};
use crate::report::Comparison;
use crate::report::plot::{self, Context};

/// The fit plot (SVG text) of `fit` on its `logs`: measured and simulated currents, with
/// each log's mechanical speed \[rad/s\] as context.
///
/// # Errors
/// Those of [`PmsmFit::comparisons`] and [`plot::fit_svg`].
pub fn fit_svg(fit: &PmsmFit, logs: &[Experiment]) -> Result<String> {
    fit_svg_of(fit, &fit.comparisons(logs)?, logs)
}

/// The fit plot (SVG text) of `fit` from its `comparisons` with `logs`, computed already.
///
/// # Errors
/// Those of [`plot::fit_svg`].
pub fn fit_svg_of(fit: &PmsmFit, comparisons: &[Comparison], logs: &[Experiment]) -> Result<String> {
    let speeds = speeds(logs, comparisons);
    let context = speeds.as_ref().map(|s| context(s));
    plot::fit_svg(fit, comparisons, context.as_ref())
}

/// The comparison plot (SVG text) of a validation's `comparisons` with its `logs`.
///
/// # Errors
/// Those of [`plot::compare_svg`].
pub fn compare_svg(comparisons: &[Comparison], logs: &[Experiment]) -> Result<String> {
    let speeds = speeds(logs, comparisons);
    let context = speeds.as_ref().map(|s| context(s));
    plot::compare_svg(comparisons, context.as_ref())
}

/// The mechanical speed of each log, when every log has it at the comparison's length.
fn speeds<'a>(logs: &'a [Experiment], comparisons: &[Comparison]) -> Option<Vec<&'a [f64]>> {
    let v: Vec<&[f64]> = logs.iter().filter_map(|e| e.channel(channel::W_M).ok()).collect();
    let same = v.len() == comparisons.len() && v.iter().zip(comparisons).all(|(s, c)| s.len() == c.len());
    same.then_some(v)
}

fn context<'a>(speeds: &'a [&'a [f64]]) -> Context<'a> {
    Context { name: "w_m", unit: "rad/s, mechanical", per_log: speeds }
}
