//! Reader for PMSM drive logs (CSV plain or gzip, Parquet, Arrow IPC) on top of
//! [`crate::data::csv`] and [`crate::data::columnar`].
//!
//! A log is a CSV file with a header line and one row per sample `t_k = k h`; the default
//! column names are `t, ud, uq, id, iq, w_m, theta_m, ud_ref, uq_ref`. Units are converted
//! to the library's SI conventions here, at the edge (MODEL.md §1): speeds mechanical
//! \[rad/s\], angles mechanical \[rad\], currents and voltages amplitude-invariant dq peak
//! values \[A\], \[V\]. The channels are named as in [`channel`](crate::pmsm::log::signals::channel).
//!
//! ```no_run
//! use greybox::pmsm::{read_log, CsvOptions};
//! let exp = read_log("data/sample.csv.gz", &CsvOptions::default())?;
//! println!("{} samples", exp.len());
//! # Ok::<(), greybox::Error>(())
//! ```

use std::ops::Range;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::data::Experiment;
use crate::data::TimeCheck;
use crate::data::csv::name_excerpt;
use crate::data::read_table_with;
use crate::data::{TimeSegments, time_segments};
use crate::error::{Error, Result};
use crate::pmsm::log::plausible::plausible;
use crate::pmsm::log::signals::check_pole_pairs;
use crate::pmsm::log::signals::{MIN_SAMPLES, PmsmError};

use super::build::{build, rename_columns};
use super::options::*;

/// Reads one PMSM drive log into a validated [`Experiment`] of N samples whose channels
/// are named as in [`channel`](crate::pmsm::log::signals::channel).
///
/// Gzip is detected by the magic bytes `1f 8b`, not by the extension; a `.parquet`,
/// `.arrow`, `.feather` or `.ipc` file is read as a columnar log
/// ([`crate::data::read_table`]) with the same names, units and checks. The
/// experiment's name is the file name without `.csv.gz` / `.csv` / `.parquet` …. Only the needed columns are parsed;
/// the others may hold anything. Fields may be surrounded by blanks; `nan` and `inf` parse
/// as numbers and are then rejected by validation. The sample time h \[s\] is the mean step
/// of the time column, which must be uniform ([`Experiment::try_from_time`]). The time
/// column is in `options.time_unit`, divided into seconds first; `options.window` then keeps
/// the rows with `from ≤ t ≤ to` \[s\] (both inclusive), and only those rows are checked
/// and kept. Row numbers in errors count the file's data rows from 0 either way.
///
/// # Errors
/// - [`PmsmError::InvalidPolePairs`] for `pole_pairs` outside `Some(1..=100)`, or `None` when
///   the speed is electrical or the dq signals come from phases (before the file is
///   opened);
/// - those of [`read_table_with`], which checks while the file streams and stops at the first
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
///   [[`MIN_SAMPLE_TIME`], [`MAX_SAMPLE_TIME`]] = \[100 ns, 100 ms\], unless `options.force`,
///   with the time unit that would explain it (`--time-unit ms` for a column in ms read as
///   s); [`Error::ImplausibleValue`] naming the column and row of a speed, current or
///   voltage beyond ±1e6 rad/s, ±1e6 A, ±1e7 V (a corrupt cell), unless `options.force`;
/// - for a window (`options.window`): [`Error::InvalidOption`] with option `from` or `to`
///   for a non-finite end or `from ≥ to` (before the file is opened), and option `window`
///   for a window holding fewer than [`MIN_SAMPLES`] samples (saying how many it holds and
///   the span of the log's time column).
///
/// A gap in the time column ([`crate::data::is_gap`]: a step back or longer than 1.5 h) is
/// an [`Error::NonUniformTime`] whose message suggests `--split-gaps`; read such a log with
/// [`read_log_segments`](crate::pmsm::read_log_segments).
///
/// Never panics. Source of the conventions: MODEL.md §1, §4.
pub fn read_log(path: impl AsRef<Path>, options: &CsvOptions) -> Result<Experiment> {
    read_log_from(LogSource::Path(path.as_ref()), options)
}

/// Where a log comes from: a file, or (feature `parquet`) Arrow record batches in memory.
#[derive(Clone, Copy, Debug)]
pub enum LogSource<'a> {
    /// A log file, its format by extension ([`read_log`]).
    Path(&'a Path),
    /// An Arrow table in memory (a pyarrow, polars or pandas table handed over by Python),
    /// read as a columnar file with the same column names, units and checks.
    #[cfg(feature = "parquet")]
    Arrow {
        /// The log's name: the experiment's, and the path errors name.
        name: &'a str,
        /// The table's schema (column names and types).
        schema: &'a arrow_schema::Schema,
        /// Its rows, batch after batch.
        batches: &'a [arrow_array::RecordBatch],
    },
}

impl<'a> LogSource<'a> {
    /// The files `paths` as sources, in order.
    pub fn files(paths: &'a [PathBuf]) -> Vec<Self> {
        paths.iter().map(|p| Self::Path(p)).collect()
    }

    /// The path of a file, or the name of a table (what errors name).
    pub fn path(&self) -> &Path {
        match self {
            Self::Path(p) => p,
            #[cfg(feature = "parquet")]
            Self::Arrow { name, .. } => Path::new(name),
        }
    }

    /// The source's columns as `spec` maps them into channels: [`crate::data::read_csv`]
    /// for a file, [`crate::data::read_spec_batches`] for a table (no PMSM column checks:
    /// a log of any other quantities).
    ///
    /// # Errors
    /// Those of [`crate::data::read_csv`] (a table's naming its name).
    pub fn read_spec(&self, spec: &crate::data::CsvSpec) -> Result<Experiment> {
        match *self {
            Self::Path(path) => crate::data::read_csv(path, spec),
            #[cfg(feature = "parquet")]
            Self::Arrow { name, schema, batches } => {
                crate::data::read_spec_batches(name, schema, batches, spec)
            }
        }
    }

    /// The wanted columns (see [`read_table_with`]).
    fn table(
        &self,
        wanted: &[(&str, bool)],
        options: &CsvOptions,
        time: TimeCheck,
    ) -> Result<crate::data::Table> {
        match *self {
            Self::Path(path) => read_table_with(path, wanted, &options.limits, options.delimiter, time),
            #[cfg(feature = "parquet")]
            Self::Arrow { name, schema, batches } => {
                crate::data::read_batches_with(name, schema, batches, wanted, &options.limits, time)
            }
        }
    }
}

/// [`read_log`] of a file or an Arrow table in memory: the same columns, units, window and
/// checks; a table's experiment is named by its `name`.
///
/// # Errors
/// Those of [`read_log`], naming the table's `name` where they name a path.
pub fn read_log_from(source: LogSource<'_>, options: &CsvOptions) -> Result<Experiment> {
    let path = source.path();
    let time = if options.window.is_open() { TimeCheck::Streaming } else { TimeCheck::Skip };
    let raw = Raw::read(source, options, time)?;
    if options.window.is_open() {
        let rows = raw.rows;
        return plausible(path, raw.into_experiment(0..rows, options)?, options);
    }
    let cut = raw.window(options)?;
    if let Some(next) = cut.segments.get(1) {
        return Err(raw.gap(next.start, cut.h, &options.columns.t));
    }
    let e = raw.into_experiment(cut.segments[0].clone(), options)?;
    plausible(path, e, options)
}

/// Reads several logs with [`read_log`], in parallel, keeping the order of `paths`.
///
/// # Errors
/// The first error, in the order of `paths`, that [`read_log`] returns for any of them.
pub fn read_logs<P: AsRef<Path> + Sync>(paths: &[P], options: &CsvOptions) -> Result<Vec<Experiment>> {
    let results: Vec<Result<Experiment>> = paths.par_iter().map(|p| read_log(p, options)).collect();
    results.into_iter().collect()
}

/// The wanted columns of one log as parsed, the time column (first) in seconds.
pub(super) struct Raw {
    path: PathBuf,
    pub(super) name: String,
    n_p: u32,
    /// Data rows.
    rows: usize,
    /// In the order of the request (`t`, the main columns, `w_m`, …).
    cols: Vec<Option<Vec<f64>>>,
}

impl Raw {
    /// Reads the wanted columns, the time column checked by the reader as `time` says
    /// ([`TimeCheck::Skip`] for a window or a split at gaps, which check the rows they keep:
    /// the time column is then split or windowed here).
    pub(super) fn read(source: LogSource<'_>, options: &CsvOptions, time: TimeCheck) -> Result<Self> {
        let path = source.path();
        options.window.check()?;
        let needs_n_p = options.speed_frame == Frame::Electrical || options.source == DqSource::Phases;
        let n_p = match options.pole_pairs {
            Some(n_p) => {
                check_pole_pairs(n_p)?;
                n_p
            }
            None if needs_n_p => return Err(PmsmError::InvalidPolePairs { n_p: 0 }.into()),
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
        let n_extra = c.extra.len();
        wanted.extend(c.extra.iter().map(|x| (x.as_str(), false)));
        let mut table = match source.table(&wanted, options, time) {
            Err(Error::TooShort { name, len, .. }) => {
                return Err(Error::TooShort { name, len, min: MIN_SAMPLES });
            }
            Err(Error::NonUniformTime { column, row, dt, expected, tolerance, gap }) => {
                // The reader saw the file's unit; the message says seconds.
                let s = options.time_unit.per_second();
                return Err(Error::NonUniformTime {
                    column,
                    row,
                    dt: dt / s,
                    expected: expected / s,
                    tolerance,
                    gap,
                });
            }
            other => other?,
        };
        if dq {
            let has = |i: usize| table.columns[i].is_some();
            let n = table.columns.len() - n_extra;
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
        let per_second = options.time_unit.per_second();
        if let Some(t) = table.columns[0].as_mut().filter(|_| per_second != 1.0) {
            t.iter_mut().for_each(|x| *x /= per_second);
        }
        Ok(Self { path: path.to_path_buf(), name: table.name, n_p, rows, cols: table.columns })
    }

    /// The time column \[s\].
    pub(super) fn t(&self) -> &[f64] {
        self.cols[0].as_deref().unwrap_or_default()
    }

    /// The rows of `options.window`, cut at the gaps.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `window`) when the window holds fewer than
    /// [`MIN_SAMPLES`] rows.
    pub(super) fn window(&self, options: &CsvOptions) -> Result<TimeSegments> {
        let cut = time_segments(self.t(), &options.window);
        if cut.in_window < MIN_SAMPLES {
            let t = self.t();
            let (first, last) =
                (t.first().copied().unwrap_or(f64::NAN), t.last().copied().unwrap_or(f64::NAN));
            return Err(Error::InvalidOption {
                option: "window".into(),
                reason: format!(
                    "the window {} holds {} samples of {} (its time column, read in {}, runs from {first} s \
                     to {last} s); at least {MIN_SAMPLES} are needed",
                    options.window.describe(),
                    cut.in_window,
                    self.path.display(),
                    options.time_unit.name(),
                ),
            });
        }
        Ok(cut)
    }

    /// The gap error at `row` for the reference step `h` \[s\] (its message suggests
    /// splitting the log).
    pub(super) fn gap(&self, row: usize, h: f64, column: &str) -> Error {
        let t = self.t();
        let dt = if row > 0 { t[row] - t[row - 1] } else { f64::NAN };
        crate::data::segments::non_uniform_time(column, row, dt, h, crate::data::TIME_TOLERANCE)
    }

    /// The experiment of rows `range` under the log's name, built from the columns
    /// themselves (cut in place, not copied).
    pub(super) fn into_experiment(mut self, range: Range<usize>, options: &CsvOptions) -> Result<Experiment> {
        let cols = std::mem::take(&mut self.cols)
            .into_iter()
            .map(|c| {
                c.map(|mut v| {
                    v.truncate(range.end);
                    v.drain(..range.start);
                    v
                })
            })
            .collect();
        build(self.name, cols, self.n_p, options)
            .map_err(|e| rename_columns(e, &options.columns, range.start))
    }

    /// The experiment of rows `range` named `name`, from copies of the rows.
    pub(super) fn build(
        &self,
        range: Range<usize>,
        name: String,
        options: &CsvOptions,
    ) -> Result<Experiment> {
        let cols = self.cols.iter().map(|c| c.as_ref().map(|v| v[range.clone()].to_vec())).collect();
        build(name, cols, self.n_p, options).map_err(|e| rename_columns(e, &options.columns, range.start))
    }
}
