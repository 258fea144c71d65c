//! CSV reader for drive logs, plain or gzip-compressed.
//!
//! A log is a CSV file with a header line and one row per sample `t_k = k h`; see
//! `../shared/data/README.md` for the column meanings the defaults assume. Units are
//! converted to the library's SI conventions here, at the edge (MODEL.md §1): speeds
//! mechanical [rad/s], angles mechanical [rad], currents and voltages amplitude-invariant
//! dq peak values [A], [V]. Everything is validated by
//! [`Experiment::try_from_time`].
//!
//! ```no_run
//! use greybox::{read_csv, CsvOptions};
//! let exp = read_csv("../shared/data/servo_spm_moves_idinj.csv.gz", 4, &CsvOptions::default())?;
//! assert_eq!(exp.len(), 72_000);
//! # Ok::<(), greybox::Error>(())
//! ```

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::transform::{currents_to_dq, stator_held_voltages_to_dq};
use super::{Experiment, Signals};
use crate::error::{Error, Result};

/// Header names of the columns a log may hold, one per signal; every name is remappable.
///
/// The defaults are the header names of the development logs in `../shared/data`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct ColumnNames {
    /// Time `t_k` [s] (required). Default `t`.
    pub t: String,
    /// d-axis voltage, period mean over `[t_k, t_k + h)` (required for [`DqSource::Dq`]).
    /// Default `ud`.
    pub u_d: String,
    /// q-axis voltage, period mean (required for [`DqSource::Dq`]). Default `uq`.
    pub u_q: String,
    /// d-axis current at `t_k` (required for [`DqSource::Dq`]). Default `id`.
    pub i_d: String,
    /// q-axis current at `t_k` (required for [`DqSource::Dq`]). Default `iq`.
    pub i_q: String,
    /// Rotor speed at `t_k` (required). Default `w_m`.
    pub w_m: String,
    /// Rotor angle at `t_k` (optional; required for [`DqSource::Phases`]). Default `theta_m`.
    pub theta_m: String,
    /// d-axis voltage reference computed at `t_k` (optional). Default `ud_ref`.
    pub u_d_ref: String,
    /// q-axis voltage reference computed at `t_k` (optional). Default `uq_ref`.
    pub u_q_ref: String,
    /// Phase-a current at `t_k` (required for [`DqSource::Phases`]). Default `ia`.
    pub i_a: String,
    /// Phase-b current at `t_k` (required for [`DqSource::Phases`]). Default `ib`.
    pub i_b: String,
    /// Phase-c current at `t_k` (required for [`DqSource::Phases`]). Default `ic`.
    pub i_c: String,
    /// Phase-a to neutral voltage, period mean (required for [`DqSource::Phases`]).
    /// Default `ua`.
    pub u_a: String,
    /// Phase-b to neutral voltage, period mean (required for [`DqSource::Phases`]).
    /// Default `ub`.
    pub u_b: String,
    /// Phase-c to neutral voltage, period mean (required for [`DqSource::Phases`]).
    /// Default `uc`.
    pub u_c: String,
}

impl Default for ColumnNames {
    fn default() -> Self {
        let s = |x: &str| x.to_string();
        Self {
            t: s("t"),
            u_d: s("ud"),
            u_q: s("uq"),
            i_d: s("id"),
            i_q: s("iq"),
            w_m: s("w_m"),
            theta_m: s("theta_m"),
            u_d_ref: s("ud_ref"),
            u_q_ref: s("uq_ref"),
            i_a: s("ia"),
            i_b: s("ib"),
            i_c: s("ic"),
            u_a: s("ua"),
            u_b: s("ub"),
            u_c: s("uc"),
        }
    }
}

/// Unit of the speed column.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpeedUnit {
    /// Radians per second (default).
    #[default]
    RadPerSec,
    /// Revolutions per minute; multiplied by `2π/60` on reading.
    Rpm,
}

/// Whether the speed and angle columns are mechanical or electrical quantities.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Frame {
    /// Mechanical speed and angle (default): `w_m`, `θ_m`.
    #[default]
    Mechanical,
    /// Electrical speed and angle `w_e = n_p w_m`, `θ_e = n_p θ_m`: divided by `n_p` on
    /// reading. A wrapped `θ_e` gives a `θ_m` in `[−π/n_p, π/n_p)`, which is all that
    /// matters for `θ_e = n_p θ_m`.
    Electrical,
}

/// Unit of the angle column.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AngleUnit {
    /// Radians (default).
    #[default]
    Rad,
    /// Degrees; multiplied by `π/180` on reading.
    Deg,
}

/// Scaling of current or voltage columns (MODEL.md §1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scale {
    /// Amplitude-invariant peak values (default), what the library uses: a phase peak `X̂`
    /// gives `|x_dq| = X̂`.
    #[default]
    Peak,
    /// RMS-scaled values (`|x_dq|` = phase RMS, as some drives log): multiplied by `√2` on
    /// reading. Power-invariant dq scaling (`|x_dq| = √(3/2)` × phase peak) is not this.
    Rms,
}

/// Where the dq currents and voltages come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DqSource {
    /// The dq columns `u_d, u_q, i_d, i_q` (default).
    #[default]
    Dq,
    /// Computed from the phase columns and `theta_m`: currents by Clarke and Park at
    /// `θ_e = n_p θ_m`, voltages as period means of a voltage held in the **stator** frame
    /// ([`stator_held_voltages_to_dq`](super::transform::stator_held_voltages_to_dq),
    /// MODEL.md §4). Phase voltages computed from a dq-held voltage (gym-electric-motor)
    /// do not fit this model; read those logs with [`DqSource::Dq`].
    Phases,
}

/// How to read a log: column names, units and the source of the dq signals.
///
/// `Default` reads the development logs in `../shared/data` as they are: SI units,
/// mechanical speed and angle, peak scaling, dq columns.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct CsvOptions {
    /// Header names of the columns.
    pub columns: ColumnNames,
    /// Unit of the speed column (default rad/s).
    pub speed_unit: SpeedUnit,
    /// Whether speed and angle are mechanical (default) or electrical.
    pub speed_frame: Frame,
    /// Unit of the angle column (default rad).
    pub angle_unit: AngleUnit,
    /// Scaling of the current columns, dq or phase (default peak).
    pub current_scale: Scale,
    /// Scaling of the voltage columns, dq, references or phase (default peak).
    pub voltage_scale: Scale,
    /// Source of the dq signals (default: the dq columns).
    pub source: DqSource,
}

/// Reads one drive log (CSV, plain or gzip) into a validated [`Experiment`] of N samples.
///
/// `n_p` is the number of pole pairs (needed for [`Frame::Electrical`] and
/// [`DqSource::Phases`], and stored in the experiment). Gzip is detected by the magic
/// bytes `1f 8b`, not by the extension. The experiment's name is the file name without
/// `.csv.gz` / `.csv` (or without its extension). Only the needed columns are parsed;
/// the others may hold anything. Fields may be surrounded by blanks; `nan` and `inf` parse
/// as numbers and are then rejected by validation. The sample time h [s] is the mean step
/// of the time column, which must be uniform ([`Experiment::try_from_time`]).
///
/// # Errors
/// - [`Error::InvalidPolePairs`] for `n_p = 0` (before the file is opened);
/// - [`Error::Io`] with the path if the file cannot be opened, read or decompressed;
/// - [`Error::MissingColumn`] naming the column and listing the header for a required
///   column not in the header (`t, ud, uq, id, iq, w_m`; for [`DqSource::Phases`]
///   `t, w_m, theta_m, ia, ib, ic, ua, ub, uc`, all under their configured names);
/// - [`Error::Csv`] with the path and 1-based line number for a row whose field count
///   differs from the header's, or a needed field that is not a number (naming the column
///   and the text found);
/// - [`Error::TooShort`] for an empty file, a header without rows, or fewer than
///   [`MIN_SAMPLES`](super::MIN_SAMPLES) rows;
/// - [`Error::NonFinite`] naming the column (as configured) and 0-based data row of a NaN
///   or ±Inf; [`Error::NonUniformTime`] for a time column that is not uniform (a dropped or
///   repeated sample), [`Error::InvalidSampleTime`] for a decreasing one.
///
/// Never panics. Source of the conventions: MODEL.md §1, §4; `../shared/data/README.md`.
pub fn read_csv(path: impl AsRef<Path>, n_p: u32, options: &CsvOptions) -> Result<Experiment> {
    let path = path.as_ref();
    if n_p == 0 {
        return Err(Error::InvalidPolePairs { n_p });
    }
    let name = experiment_name(path);
    let Some(raw) = read_columns(path, options)? else {
        return Err(Error::TooShort { name, len: 0, min: super::MIN_SAMPLES });
    };
    build(name, raw, n_p, options).map_err(|e| rename_columns(e, &options.columns))
}

/// Reads several logs with [`read_csv`], in parallel, keeping the order of `paths`.
///
/// Returns one [`Experiment`] per path.
///
/// # Errors
/// The first error, in the order of `paths`, that [`read_csv`] returns for any of them.
pub fn read_csv_many<P: AsRef<Path> + Sync>(
    paths: &[P],
    n_p: u32,
    options: &CsvOptions,
) -> Result<Vec<Experiment>> {
    let results: Vec<Result<Experiment>> = paths.par_iter().map(|p| read_csv(p, n_p, options)).collect();
    results.into_iter().collect()
}

/// Where the dq signals come from: indices into [`RawColumns::values`].
enum Main {
    /// `[u_d, u_q, i_d, i_q]`.
    Dq([usize; 4]),
    /// `[i_a, i_b, i_c, u_a, u_b, u_c]` and `theta_m`.
    Phases([usize; 6], usize),
}

/// The parsed columns, in header-independent slots.
struct RawColumns {
    t: usize,
    w_m: usize,
    main: Main,
    theta_m: Option<usize>,
    u_d_ref: Option<usize>,
    u_q_ref: Option<usize>,
    values: Vec<Vec<f64>>,
}

/// Parses the needed columns; `Ok(None)` for a file without any header.
fn read_columns(path: &Path, options: &CsvOptions) -> Result<Option<RawColumns>> {
    let io_err = |source| Error::Io { path: path.to_path_buf(), source };
    let file = File::open(path).map_err(io_err)?;
    let mut buf = BufReader::with_capacity(1 << 16, file);
    let head = buf.fill_buf().map_err(io_err)?;
    let gz = head.starts_with(&[0x1f, 0x8b]);
    let reader: Box<dyn Read> =
        if gz { Box::new(flate2::read::MultiGzDecoder::new(buf)) } else { Box::new(buf) };
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(false)
        .trim(csv::Trim::All)
        .buffer_capacity(1 << 16)
        .from_reader(reader);

    let header: Vec<String> = rdr
        .byte_headers()
        .map_err(|e| csv_error(path, e))?
        .iter()
        .map(|f| String::from_utf8_lossy(f).into_owned())
        .collect();
    if header.iter().all(String::is_empty) {
        return Ok(None);
    }

    let find = |c: &str| header.iter().position(|h| h == c);
    let require = |c: &str| {
        find(c).ok_or_else(|| Error::MissingColumn {
            path: path.to_path_buf(),
            column: c.to_string(),
            available: header.join(", "),
        })
    };
    // Header index of each parsed column; the slots of `RawColumns` index into this list.
    let mut wanted: Vec<usize> = Vec::new();
    let mut add = |idx: usize| {
        wanted.push(idx);
        wanted.len() - 1
    };
    let c = &options.columns;
    // Required columns in a fixed order: the error names the first one missing.
    let t = add(require(&c.t)?);
    let main = match options.source {
        DqSource::Dq => {
            let mut m = [0; 4];
            for (slot, name) in m.iter_mut().zip([&c.u_d, &c.u_q, &c.i_d, &c.i_q]) {
                *slot = add(require(name)?);
            }
            Main::Dq(m)
        }
        DqSource::Phases => {
            let mut m = [0; 6];
            for (slot, name) in m.iter_mut().zip([&c.i_a, &c.i_b, &c.i_c, &c.u_a, &c.u_b, &c.u_c]) {
                *slot = add(require(name)?);
            }
            Main::Phases(m, add(require(&c.theta_m)?))
        }
    };
    let w_m = add(require(&c.w_m)?);
    let theta_m = match main {
        Main::Dq(_) => find(&c.theta_m).map(&mut add),
        Main::Phases(_, th) => Some(th),
    };
    let u_d_ref = find(&c.u_d_ref).map(&mut add);
    let u_q_ref = find(&c.u_q_ref).map(&mut add);

    let mut values: Vec<Vec<f64>> = vec![Vec::new(); wanted.len()];
    let mut record = csv::ByteRecord::new();
    let mut row = 0usize;
    while rdr.read_byte_record(&mut record).map_err(|e| csv_error(path, e))? {
        for (column, &idx) in values.iter_mut().zip(&wanted) {
            // flexible(false) guarantees `record.len() == header.len()` > idx.
            let field = record.get(idx).unwrap_or_default();
            match parse_f64(field) {
                Some(x) => column.push(x),
                None => {
                    return Err(Error::Csv {
                        path: path.to_path_buf(),
                        line: record.position().map_or(0, csv::Position::line),
                        message: format!(
                            "column `{}` (data row {row}): cannot parse `{}` as a number",
                            header[idx],
                            String::from_utf8_lossy(field)
                        ),
                    });
                }
            }
        }
        row += 1;
    }
    Ok(Some(RawColumns { t, w_m, main, theta_m, u_d_ref, u_q_ref, values }))
}

fn parse_f64(field: &[u8]) -> Option<f64> {
    std::str::from_utf8(field).ok()?.parse::<f64>().ok()
}

/// Converts units, derives dq from phases if asked, and validates.
fn build(name: String, raw: RawColumns, n_p: u32, options: &CsvOptions) -> Result<Experiment> {
    let RawColumns { mut values, .. } = raw;
    let mut take = |i: usize| std::mem::take(&mut values[i]);
    let t = take(raw.t);
    let mut w_m = take(raw.w_m);
    let mut theta_m = raw.theta_m.map(&mut take);
    let mut u_d_ref = raw.u_d_ref.map(&mut take);
    let mut u_q_ref = raw.u_q_ref.map(&mut take);

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

    let (u_d, u_q, i_d, i_q) = match raw.main {
        Main::Dq(slots) => {
            let [mut u_d, mut u_q, mut i_d, mut i_q] = slots.map(&mut take);
            scale_in_place(&mut u_d, u_scale);
            scale_in_place(&mut u_q, u_scale);
            scale_in_place(&mut i_d, i_scale);
            scale_in_place(&mut i_q, i_scale);
            (u_d, u_q, i_d, i_q)
        }
        Main::Phases(slots, _) => {
            let mut ph = slots.map(&mut take);
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
            let [i_a, i_b, i_c, u_a, u_b, u_c] = &ph;
            let (i_d, i_q) = currents_to_dq(i_a, i_b, i_c, th, n_p)?;
            let (u_d, u_q) = stator_held_voltages_to_dq(u_a, u_b, u_c, th, &w_m, h, n_p)?;
            (u_d, u_q, i_d, i_q)
        }
    };
    let signals = Signals { u_d, u_q, i_d, i_q, w_m, theta_m, u_d_ref, u_q_ref };
    Experiment::try_from_time(name, &t, n_p, signals)
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

fn csv_error(path: &Path, e: csv::Error) -> Error {
    let line = e.position().map_or(0, |p| p.line());
    match e.into_kind() {
        csv::ErrorKind::Io(source) => Error::Io { path: path.to_path_buf(), source },
        csv::ErrorKind::UnequalLengths { expected_len, len, .. } => Error::Csv {
            path: path.to_path_buf(),
            line,
            message: format!("row has {len} fields, the header has {expected_len}"),
        },
        other => Error::Csv { path: path.to_path_buf(), line, message: format!("{other:?}") },
    }
}

/// File name without `.gz` and then without its extension (`.csv`).
fn experiment_name(path: &Path) -> String {
    let file = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let file = file.strip_suffix(".gz").unwrap_or(&file);
    let stem = Path::new(file).file_stem().map(|s| s.to_string_lossy().into_owned());
    stem.unwrap_or_else(|| file.to_string())
}
