//! Reader for PMSM drive logs (CSV plain or gzip, Parquet, Arrow IPC) on top of
//! [`crate::data::csv`] and [`crate::data::columnar`].
//!
//! A log is a CSV file with a header line and one row per sample `t_k = k h`; the default
//! column names are `t, ud, uq, id, iq, w_m, theta_m, ud_ref, uq_ref`. Units are converted
//! to the library's SI conventions here, at the edge (MODEL.md §1): speeds mechanical
//! \[rad/s\], angles mechanical \[rad\], currents and voltages amplitude-invariant dq peak
//! values \[A\], \[V\]. The channels are named as in [`channel`](super::signals::channel).
//!
//! ```no_run
//! use greybox::pmsm::{read_log, CsvOptions};
//! let exp = read_log("data/sample.csv.gz", &CsvOptions::default())?;
//! println!("{} samples", exp.len());
//! # Ok::<(), greybox::Error>(())
//! ```

use std::path::Path;

use rayon::prelude::*;

use super::interval::check_pole_pairs;
use super::signals::{DqSignals, DqView, MIN_SAMPLES};
use super::transform::{currents_to_dq, stator_held_voltages_to_dq};
use crate::data::Experiment;
use crate::data::columnar::read_table;
use crate::data::csv::name_excerpt;
use crate::error::{Error, Result};

mod options;
pub use options::*;

/// Reads one PMSM drive log into a validated [`Experiment`] of N samples whose channels
/// are named as in [`channel`](super::signals::channel).
///
/// Gzip is detected by the magic bytes `1f 8b`, not by the extension; a `.parquet`,
/// `.arrow`, `.feather` or `.ipc` file is read as a columnar log
/// ([`crate::data::columnar::read_table`]) with the same names, units and checks. The
/// experiment's name is the file name without `.csv.gz` / `.csv` / `.parquet` …. Only the needed columns are parsed;
/// the others may hold anything. Fields may be surrounded by blanks; `nan` and `inf` parse
/// as numbers and are then rejected by validation. The sample time h \[s\] is the mean step
/// of the time column, which must be uniform ([`Experiment::try_from_time`]).
///
/// # Errors
/// - [`Error::InvalidPolePairs`] for `pole_pairs` outside `Some(1..=100)`, or `None` when
///   the speed is electrical or the dq signals come from phases (before the file is
///   opened);
/// - those of [`read_table`], which checks while the file streams and stops at the first
///   bad row: [`Error::LimitExceeded`] for a file beyond `options.limits`,
///   [`Error::DuplicateColumn`] for a wanted column named twice in the header,
///   [`Error::Io`], [`Error::MissingColumn`] for a required
///   column (`t, ud, uq, id, iq, w_m`, where `ud, uq` may be absent when both `ud_ref,
///   uq_ref` are logged: such a log can only be fitted from its reference; for
///   [`DqSource::Phases`]
///   `t, ia, ib, ic, ua, ub, uc, theta_m, w_m`, all under their configured names),
///   [`Error::Csv`] with the line number; for a columnar log [`Error::ColumnType`] naming
///   a wanted column that is not numeric and [`Error::Format`] for a malformed file, a null
///   or a build without the cargo feature `parquet`;
/// - [`Error::TooShort`] for an empty file or fewer than [`MIN_SAMPLES`] rows;
/// - [`Error::NonFinite`] naming the column (as configured) and 0-based data row of a NaN
///   or ±Inf; [`Error::NonUniformTime`] for a time column that is not uniform (a dropped or
///   repeated sample), [`Error::InvalidSampleTime`] for a decreasing one;
/// - [`Error::ImplausibleSampleTime`] naming the log for h outside
///   [[`MIN_SAMPLE_TIME`], [`MAX_SAMPLE_TIME`]] = \[100 ns, 100 ms\], unless `options.force`.
///
/// Never panics. Source of the conventions: MODEL.md §1, §4.
pub fn read_log(path: impl AsRef<Path>, options: &CsvOptions) -> Result<Experiment> {
    let path = path.as_ref();
    let needs_n_p = options.speed_frame == Frame::Electrical || options.source == DqSource::Phases;
    let n_p = match options.pole_pairs {
        Some(n_p) => {
            check_pole_pairs(n_p)?;
            n_p
        }
        None if needs_n_p => return Err(Error::InvalidPolePairs { n_p: 0 }),
        None => 1,
    };
    let c = &options.columns;
    let main: Vec<&String> = match options.source {
        DqSource::Dq => vec![&c.u_d, &c.u_q, &c.i_d, &c.i_q],
        DqSource::Phases => vec![&c.i_a, &c.i_b, &c.i_c, &c.u_a, &c.u_b, &c.u_c, &c.theta_m],
    };
    // Required columns in a fixed order: the error names the first one missing.
    // The terminal voltage may be absent when the reference is logged (checked below).
    let dq = options.source == DqSource::Dq;
    let mut wanted: Vec<(&str, bool)> = vec![(&c.t, true)];
    wanted.extend(main.iter().enumerate().map(|(i, n)| (n.as_str(), !(dq && i < 2))));
    wanted.push((&c.w_m, true));
    if options.source == DqSource::Dq {
        wanted.push((&c.theta_m, false));
    }
    wanted.extend([(c.u_d_ref.as_str(), false), (c.u_q_ref.as_str(), false)]);
    let table = match read_table(path, &wanted, &options.limits, options.delimiter) {
        Err(Error::TooShort { name, len, .. }) => {
            return Err(Error::TooShort { name, len, min: MIN_SAMPLES });
        }
        other => other?,
    };
    if dq {
        let has = |i: usize| table.columns[i].is_some();
        let n = table.columns.len();
        let (terminal, reference) = (has(1) && has(2), has(n - 2) && has(n - 1));
        if !terminal && (!reference || has(1) || has(2)) {
            let missing = if has(1) { &c.u_q } else { &c.u_d };
            return Err(Error::MissingColumn {
                path: path.to_path_buf(),
                column: missing.clone(),
                available: table
                    .header
                    .iter()
                    .map(|h| name_excerpt(h.as_bytes()))
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
    }
    let rows = table.columns[0].as_ref().map_or(0, Vec::len);
    if rows < MIN_SAMPLES {
        return Err(Error::TooShort { name: table.name, len: rows, min: MIN_SAMPLES });
    }
    let e =
        build(table.name, table.columns, n_p, options).map_err(|e| rename_columns(e, &options.columns))?;
    if !options.force && !(MIN_SAMPLE_TIME..=MAX_SAMPLE_TIME).contains(&e.h()) {
        return Err(Error::ImplausibleSampleTime {
            path: path.to_path_buf(),
            h: e.h(),
            min: MIN_SAMPLE_TIME,
            max: MAX_SAMPLE_TIME,
        });
    }
    Ok(e)
}

/// Reads several logs with [`read_log`], in parallel, keeping the order of `paths`.
///
/// # Errors
/// The first error, in the order of `paths`, that [`read_log`] returns for any of them.
pub fn read_logs<P: AsRef<Path> + Sync>(paths: &[P], options: &CsvOptions) -> Result<Vec<Experiment>> {
    let results: Vec<Result<Experiment>> = paths.par_iter().map(|p| read_log(p, options)).collect();
    results.into_iter().collect()
}

/// Converts units, derives dq from phases if asked, and validates. `cols` are in the
/// order of [`read_log`]'s request.
fn build(name: String, cols: Vec<Option<Vec<f64>>>, n_p: u32, options: &CsvOptions) -> Result<Experiment> {
    let phases = options.source == DqSource::Phases;
    let mut cols = cols.into_iter();
    let mut next = || cols.next().flatten();
    let t = next().unwrap_or_default();
    let main: Vec<Vec<f64>> = (0..if phases { 7 } else { 4 }).map(|_| next().unwrap_or_default()).collect();
    let mut w_m = next().unwrap_or_default();
    let mut theta_m = if phases { main.get(6).cloned() } else { next() };
    let mut u_d_ref = next();
    let mut u_q_ref = next();

    let frame = match options.speed_frame {
        Frame::Mechanical => 1.0,
        Frame::Electrical => 1.0 / f64::from(n_p),
    };
    let speed = frame
        * match options.speed_unit {
            SpeedUnit::RadPerSec => 1.0,
            SpeedUnit::Rpm => std::f64::consts::PI / 30.0,
        };
    let angle = frame
        * match options.angle_unit {
            AngleUnit::Rad => 1.0,
            AngleUnit::Deg => std::f64::consts::PI / 180.0,
        };
    let scale = |s: Scale| match s {
        Scale::Peak => 1.0,
        Scale::Rms => std::f64::consts::SQRT_2,
    };
    let (i_scale, u_scale) = (scale(options.current_scale), scale(options.voltage_scale));
    scale_in_place(&mut w_m, speed);
    if let Some(v) = theta_m.as_mut() {
        scale_in_place(v, angle);
    }
    for v in [u_d_ref.as_mut(), u_q_ref.as_mut()].into_iter().flatten() {
        scale_in_place(v, u_scale);
    }

    let (u_d, u_q, i_d, i_q) = match <[Vec<f64>; 4]>::try_from(main) {
        Ok([mut u_d, mut u_q, mut i_d, mut i_q]) => {
            scale_in_place(&mut u_d, u_scale);
            scale_in_place(&mut u_q, u_scale);
            scale_in_place(&mut i_d, i_scale);
            scale_in_place(&mut i_q, i_scale);
            (u_d, u_q, i_d, i_q)
        }
        Err(main) => {
            let mut ph: Vec<Vec<f64>> = main.into_iter().take(6).collect();
            for (k, v) in ph.iter_mut().enumerate() {
                scale_in_place(v, if k < 3 { i_scale } else { u_scale });
            }
            let th = theta_m.as_deref().unwrap_or_default();
            // The transforms mix columns and neighbouring rows, so a NaN would surface
            // under a dq name: report the raw column instead.
            let c = &options.columns;
            let names = [&c.i_a, &c.i_b, &c.i_c, &c.u_a, &c.u_b, &c.u_c, &c.theta_m, &c.w_m];
            let cols = ph.iter().map(Vec::as_slice).chain([th, &w_m[..]]);
            for (col, v) in names.into_iter().zip(cols) {
                if let Some((row, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                    return Err(Error::NonFinite { column: col.clone(), row, value });
                }
            }
            let h = mean_step(&t);
            let [i_a, i_b, i_c, u_a, u_b, u_c] = &ph[..] else {
                return Err(Error::Numerical {
                    context: "phase columns".into(),
                    reason: "six expected".into(),
                });
            };
            let (i_d, i_q) = currents_to_dq(i_a, i_b, i_c, th, n_p)?;
            let (u_d, u_q) = stator_held_voltages_to_dq(u_a, u_b, u_c, th, &w_m, h, n_p)?;
            (u_d, u_q, i_d, i_q)
        }
    };
    let signals = DqSignals { u_d, u_q, i_d, i_q, w_m, theta_m, u_d_ref, u_q_ref };
    let e = Experiment::try_from_time(name, "t", &t, signals.into_channels())?;
    DqView::try_new(&e)?;
    Ok(e)
}

fn scale_in_place(v: &mut [f64], f: f64) {
    if f != 1.0 {
        v.iter_mut().for_each(|x| *x *= f);
    }
}

/// `(t[N−1] − t[0])/(N − 1)`, or NaN below two samples (validation then rejects the log).
fn mean_step(t: &[f64]) -> f64 {
    match t {
        [first, .., last] => (last - first) / (t.len() - 1) as f64,
        _ => f64::NAN,
    }
}

/// Replaces the library's signal names in validation errors by the configured header names.
fn rename_columns(e: Error, c: &ColumnNames) -> Error {
    let map = |col: String| -> String {
        let configured = match col.as_str() {
            "t" => &c.t,
            "ud" => &c.u_d,
            "uq" => &c.u_q,
            "id" => &c.i_d,
            "iq" => &c.i_q,
            "w_m" => &c.w_m,
            "theta_m" => &c.theta_m,
            "ud_ref" => &c.u_d_ref,
            "uq_ref" => &c.u_q_ref,
            _ => return col,
        };
        configured.clone()
    };
    match e {
        Error::NonFinite { column, row, value } => Error::NonFinite { column: map(column), row, value },
        Error::NonUniformTime { column, row, dt, expected, tolerance } => {
            Error::NonUniformTime { column: map(column), row, dt, expected, tolerance }
        }
        other => other,
    }
}
