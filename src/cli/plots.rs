//! `--plot` and `--residuals` of `fit`, `validate` and `track`: the library's plots and
//! residual export, with the speed of each log as context and the truth beside a
//! simulated log.

use crate::Experiment;
use crate::data::Staged;
use crate::drive::{DriveLog, Truth, plant_at};
use crate::online::Trajectory;
use crate::online::{TrackRun, TrackTruth, track_svg};
use crate::pmsm::PmsmFit;
use crate::report::Comparison;
use crate::report::plot;
use std::path::{Path, PathBuf};

/// Writes the fit plot and the residual CSV of `fit` on its `logs`, where asked.
pub fn fit_outputs(
    staged: &mut Staged,
    plot_path: Option<&Path>,
    residuals: Option<&Path>,
    fit: &PmsmFit,
    logs: &[Experiment],
) -> crate::Result<()> {
    if plot_path.is_none() && residuals.is_none() {
        return Ok(());
    }
    if fit.steady_state() {
        return Err(crate::Error::InvalidOption {
            option: if plot_path.is_some() { "plot" } else { "residuals" }.into(),
            reason: "the log was fitted by the steady-state equations (its sample time is too long for the dynamic \
                     model, or its voltage is point-sampled: the report's note says which), which simulate no currents to plot: drop --plot and --residuals"
                .into(),
        });
    }
    let comparisons = fit.comparisons(logs)?;
    if let Some(path) = residuals {
        staged.produce(path, |tmp| crate::report::residuals::write_residuals_csv(tmp, &comparisons))?;
    }
    if let Some(path) = plot_path {
        let svg = crate::app::plots::fit_svg_of(fit, &comparisons, logs)?;
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
) -> crate::Result<()> {
    let svg = crate::app::plots::compare_svg(comparisons, logs)?;
    staged.produce(path, |tmp| plot::write_svg(tmp, &svg))
}

/// Writes the observer plot of the runs `(log path, segment, trajectory)` (a segment of a
/// log split at its gaps is drawn as `LOG#k`), with the truth of each
/// log read from the JSON beside it when there is one.
pub fn track_plot(
    staged: &mut Staged,
    path: &Path,
    runs: &[(PathBuf, Option<usize>, Trajectory)],
) -> crate::Result<()> {
    let names: Vec<String> = runs
        .iter()
        .map(|(p, segment, _)| segment.map_or_else(|| short_name(p), |k| format!("{}#{k}", short_name(p))))
        .collect();
    let truths: Vec<Option<TrackTruth>> = runs.iter().map(|(p, _, tr)| truth(p, tr)).collect();
    let runs: Vec<TrackRun<'_>> = runs
        .iter()
        .zip(&names)
        .zip(&truths)
        .map(|(((_, _, tr), name), truth)| TrackRun { name, trajectory: tr, truth: truth.as_ref() })
        .collect();
    let svg = track_svg(&runs)?;
    staged.produce(path, |tmp| plot::write_svg(tmp, &svg))
}

/// Points of a time-varying truth over the observer's time span.
const TRUTH_POINTS: usize = 400;

/// The truth of a log from the truth file `greybox simulate` wrote beside it
/// (`LOG.truth.json`, or `LOG.json` from before that name): the plant's K_e and R_s over the
/// trajectory's times, following the scenario's ramps and temperatures (`plant_at`) when
/// they change within the record; `None` when there is no truth file (another tool's
/// description of a log is not read: the plot shows no truth then).
fn truth(log: &Path, trajectory: &Trajectory) -> Option<TrackTruth> {
    let legacy = DriveLog::truth_path(log).with_extension("").with_extension("json");
    let text = [DriveLog::truth_path(log), legacy].iter().find_map(|p| std::fs::read_to_string(p).ok())?;
    let truth: Truth = serde_json::from_str(&text).ok()?;
    if !truth.time_varying {
        return Some(TrackTruth::constant(truth.k_e, truth.start.r_s));
    }
    let (t0, t1) = (trajectory.t.first().copied()?, trajectory.t.last().copied()?);
    let t: Vec<f64> =
        (0..TRUTH_POINTS).map(|k| t0 + (t1 - t0) * k as f64 / (TRUTH_POINTS - 1) as f64).collect();
    let plant: Vec<_> = t.iter().map(|&t| plant_at(&truth.config, t)).collect();
    // K_e = √(3/2) n_p ψ_f (MODEL.md §2).
    let k_e = plant.iter().map(|p| (1.5f64).sqrt() * f64::from(p.n_p) * p.psi_f).collect();
    Some(TrackTruth { t, k_e, r_s: plant.iter().map(|p| p.r_s).collect() })
}

/// The log's file name without `.gz` and `.csv`.
fn short_name(p: &Path) -> String {
    let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    name.strip_suffix(".csv").unwrap_or(name).to_string()
}
