//! The logs of a mechanical fit that needs no electrical model (a given `K_t` or `K_f`),
//! and a linear motor's logs as a shaft's.

use crate::Experiment;
use crate::app::LogReading;
use crate::data::{ColumnMap, CsvSpec, TimeWindow};
use crate::error::{Error, Result};
use crate::pmsm::{Axis, DqSource, LOAD_TORQUE, LogSource};
use std::path::PathBuf;

/// A linear motor's log `e` (speed `w_m` in m/s, position `theta_m` in m) as the shaft of
/// `axis`: both times `2π/lead` \[rad/m\].
///
/// # Errors
/// Those of [`Experiment::with_channel`].
pub(super) fn linear_motor(e: Experiment, axis: Axis) -> Result<Experiment> {
    let r = axis.radians_per_unit();
    let mut e = e;
    for (name, unit) in [("w_m", "rad/s"), ("theta_m", "rad")] {
        if let Some(c) = e.get(name) {
            let values = c.values.iter().map(|v| v * r).collect();
            e = e.with_channel(crate::data::Channel::new(name, unit, values))?;
        }
    }
    Ok(e)
}

/// The logs `sources` (files or tables) of a given `K_t`, which needs no electrical fit: only the time, `iq`,
/// the speed, the angle with `gravity` and the load column `col_load` where present are
/// read (the voltages and `id` may be absent), with the `reading`'s units, frames and
/// scales at `pole_pairs`, and its window keeps its rows.
///
/// # Errors
/// [`Error::InvalidOption`] for phase currents (`--dq-from-phases`) or `--split-gaps`,
/// which need the electrical reader, and for a window that keeps fewer than 2 rows; bad
/// paths; those of [`LogSource::read_spec`] (a missing column named with its flag).
pub(super) fn read_mechanical(
    sources: &[LogSource<'_>],
    reading: &LogReading,
    pole_pairs: u32,
    gravity: bool,
    col_load: &str,
) -> Result<Vec<Experiment>> {
    let paths: Vec<PathBuf> =
        sources.iter().filter(|s| matches!(s, LogSource::Path(_))).map(|s| s.path().to_path_buf()).collect();
    crate::app::check_paths(&paths)?;
    let o = &reading.csv;
    for (flag, set) in
        [("--dq-from-phases", o.source == DqSource::Phases), ("--split-gaps", reading.split_gaps)]
    {
        if set {
            return Err(Error::InvalidOption {
                option: flag.into(),
                reason: "not with --k-t, which reads iq and the speed only: give the dq current column"
                    .into(),
            });
        }
    }
    let c = &o.columns;
    let n_p = pole_pairs;
    let column = |col: &str, channel: &str, unit: &str, scale: f64, required: bool| ColumnMap {
        scale,
        required,
        ..ColumnMap::new(col, channel, unit)
    };
    let spec = CsvSpec {
        time: c.t.clone(),
        time_scale: 1.0 / o.time_unit.per_second(),
        columns: vec![
            column(&c.i_q, "iq", "A", o.current_scale.factor(), true),
            column(&c.w_m, "w_m", "rad/s", o.speed_factor(n_p), true),
            column(&c.theta_m, "theta_m", "rad", o.angle_factor(n_p), gravity),
            column(col_load, LOAD_TORQUE, "N m", 1.0, false),
        ],
        limits: o.limits,
        delimiter: o.delimiter,
    };
    let flag = |col: &str| match col {
        x if x == c.i_q => "--col-iq",
        x if x == c.w_m => "--col-w",
        x if x == c.theta_m => "--col-theta",
        x if x == c.t => "--col-t",
        _ => "--col-load",
    };
    sources
        .iter()
        .map(|source| {
            let e = source.read_spec(&spec).map_err(|e| match e {
                Error::MissingColumn { path, column, available } => Error::InvalidOption {
                    option: flag(&column).into(),
                    reason: format!("{}: no column `{column}` (header: {available})", path.display()),
                },
                e => e,
            })?;
            windowed(e, &o.window)
        })
        .collect()
}

/// The rows of `e` whose times `t0 + k h` \[s\] the window keeps (`from ≤ t ≤ to`, both
/// optional: [`TimeWindow::contains`]).
///
/// # Errors
/// [`Error::InvalidOption`] (`--from/--to`) when fewer than 2 rows are kept.
fn windowed(e: Experiment, window: &TimeWindow) -> Result<Experiment> {
    if window.from.is_none() && window.to.is_none() {
        return Ok(e);
    }
    let kept = |k: &usize| window.contains(e.t0() + *k as f64 * e.h());
    let first = (0..e.len()).find(kept).unwrap_or(e.len());
    let end = (first..e.len()).take_while(kept).last().map_or(first, |k| k + 1);
    if end < first + 2 {
        return Err(Error::InvalidOption {
            option: "--from/--to".into(),
            reason: format!("{}: the window keeps {} rows; it needs at least 2", e.name(), end - first),
        });
    }
    e.slice(first..end)
}
