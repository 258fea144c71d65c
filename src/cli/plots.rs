//! `--plot` and `--residuals` of `fit`, `validate` and `track`: the library's plots and
//! residual export, with the speed of each log as context and the truth beside a
//! simulated log.

use greybox::Experiment;
use greybox::data::staged::Staged;
use greybox::drive::DriveLog;
use greybox::online::Trajectory;
use greybox::online::plot::{TrackRun, TrackTruth, track_svg};
use greybox::pmsm::{PmsmFit, channel};
use greybox::report::Comparison;
use greybox::report::plot::{self, Context};
use std::path::{Path, PathBuf};

/// Writes the fit plot and the residual CSV of `fit` on its `logs`, where asked.
pub fn fit_outputs(
    staged: &mut Staged,
    plot_path: Option<&Path>,
    residuals: Option<&Path>,
    fit: &PmsmFit,
    logs: &[Experiment],
) -> greybox::Result<()> {
    if plot_path.is_none() && residuals.is_none() {
        return Ok(());
    }
    let comparisons = fit.comparisons(logs)?;
    if let Some(path) = residuals {
        staged.produce(path, |tmp| greybox::report::residuals::write_residuals_csv(tmp, &comparisons))?;
    }
    if let Some(path) = plot_path {
        let speeds = speeds(logs, &comparisons);
        let context = speeds.as_ref().map(|s| context(s));
        let svg = plot::fit_svg(fit, &comparisons, context.as_ref())?;
        staged.produce(path, |tmp| plot::write_svg(tmp, &svg))?;
    }
    Ok(())
}

/// Writes the compare plot of a validation.
pub fn compare_plot(
    staged: &mut Staged,
    path: &Path,
    comparisons: &[Comparison],
    logs: &[Experiment],
) -> greybox::Result<()> {
    let speeds = speeds(logs, comparisons);
    let context = speeds.as_ref().map(|s| context(s));
    let svg = plot::compare_svg(comparisons, context.as_ref())?;
    staged.produce(path, |tmp| plot::write_svg(tmp, &svg))
}

/// Writes the observer plot of the runs `(log path, segment, trajectory)` (a segment of a
/// log split at its gaps is drawn as `LOG#k`), with the truth of each
/// log read from the JSON beside it when there is one.
pub fn track_plot(
    staged: &mut Staged,
    path: &Path,
    runs: &[(PathBuf, Option<usize>, Trajectory)],
) -> greybox::Result<()> {
    let names: Vec<String> = runs
        .iter()
        .map(|(p, segment, _)| segment.map_or_else(|| short_name(p), |k| format!("{}#{k}", short_name(p))))
        .collect();
    let runs: Vec<TrackRun<'_>> = runs
        .iter()
        .zip(&names)
        .map(|((p, _, tr), name)| TrackRun { name, trajectory: tr, truth: truth(p) })
        .collect();
    let svg = track_svg(&runs)?;
    staged.produce(path, |tmp| plot::write_svg(tmp, &svg))
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

/// The truth of a log from the JSON `greybox simulate` wrote beside it (`k_e`,
/// `start.r_s`); `None` when there is none or it is not one (another tool's description
/// of a log is not read: the plot shows no truth then).
fn truth(log: &Path) -> Option<TrackTruth> {
    let text = std::fs::read_to_string(DriveLog::truth_path(log)).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    let k_e = v.get("k_e")?.as_f64()?;
    let r_s = v.pointer("/start/r_s")?.as_f64()?;
    Some(TrackTruth { k_e, r_s })
}

/// The log's file name without `.gz` and `.csv`.
fn short_name(p: &Path) -> String {
    let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    name.strip_suffix(".csv").unwrap_or(name).to_string()
}
