//! CSV reader, plain or gzip-compressed: any column to any channel, units converted here.
//!
//! A log is a CSV file with a header line and one row per sample `t_k = k h`. A
//! [`CsvSpec`] names the time column and, for each channel wanted, the column it comes
//! from, its unit and the factor that converts the column to that SI unit. Only the named
//! columns are parsed; the others may hold anything. Domain readers (the PMSM log reader
//! [`crate::pmsm::read_log`]) build on [`read_table`].
//!
//! ```no_run
//! use greybox::data::csv::{read_csv, ColumnMap, CsvSpec};
//! let spec = CsvSpec {
//!     columns: vec![ColumnMap::new("p_cu", "p_cu", "W"), ColumnMap::new("temp", "T_w", "K")],
//!     ..Default::default()
//! };
//! let e = read_csv("winding.csv", &spec)?;
//! println!("{} samples every {} s", e.len(), e.h());
//! # Ok::<(), greybox::Error>(())
//! ```

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Channel, Experiment, TimeCheck};
pub use delimiter::Delimiter;
use line_limit::LineTooLong;

mod chunk;
mod delimiter;
mod float;
mod line_limit;
mod quoted;
mod source;
mod table;
use crate::error::{Error, Result};

/// One column read into one channel: `channel = scale × column` \[unit\].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ColumnMap {
    /// Header name of the column.
    pub column: String,
    /// Name of the channel it becomes.
    pub channel: String,
    /// SI unit of the channel after scaling.
    pub unit: String,
    /// Factor from the column's unit to the channel's (1 when already SI).
    pub scale: f64,
    /// Whether a missing column is an error (`true`) or the channel is left out.
    pub required: bool,
}

impl ColumnMap {
    /// A required column read as it is (scale 1).
    pub fn new(column: &str, channel: &str, unit: &str) -> Self {
        Self { column: column.into(), channel: channel.into(), unit: unit.into(), scale: 1.0, required: true }
    }
}

/// How to read a log into channels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CsvSpec {
    /// Header name of the time column `t_k` [s after `time_scale`]. Default `t`.
    pub time: String,
    /// Factor from the time column's unit to seconds (1e-3 for ms). Default 1.
    pub time_scale: f64,
    /// The channels to read.
    pub columns: Vec<ColumnMap>,
    /// Bounds on line length, field count and rows (defaults a real log never reaches).
    pub limits: ReadLimits,
    /// The field delimiter of a CSV file (default `,`); Parquet and Arrow files ignore it.
    pub delimiter: Delimiter,
}

impl Default for CsvSpec {
    fn default() -> Self {
        Self {
            time: "t".into(),
            time_scale: 1.0,
            columns: Vec::new(),
            limits: ReadLimits::default(),
            delimiter: Delimiter::default(),
        }
    }
}

/// Bounds that keep a read's memory proportional to the data it accepts, whatever the file
/// (a gzip of a gigabyte of commas is 1 MB). Each is checked while the file streams: the
/// read stops with [`Error::LimitExceeded`] at the line that passes it, before buffering it.
///
/// The defaults are far beyond any drive log (a 30-column log at 100 kHz for 15 minutes is
/// 10⁸ rows of about 300 bytes); raise them for larger files.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReadLimits {
    /// Longest line (record) in bytes, terminator excluded. Default 1 MiB.
    pub max_line_bytes: u64,
    /// Most header fields (columns). Default 4096.
    pub max_fields: usize,
    /// Most data rows (samples), header excluded. Default 10⁸.
    pub max_rows: u64,
}

impl Default for ReadLimits {
    fn default() -> Self {
        Self { max_line_bytes: 1 << 20, max_fields: 4096, max_rows: 100_000_000 }
    }
}

/// Longest excerpt of a cell quoted in an error, in characters.
pub const QUOTE_CHARS: usize = 80;

/// Columns parsed from a file: one entry per requested column, `None` when an optional
/// column is absent. Every value is finite and the first column (time) passed
/// [`TimeSteps::push`](super::TimeSteps::push).
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Experiment name: the file name without `.gz` and then without its extension.
    pub name: String,
    /// The header's column names.
    pub header: Vec<String>,
    /// Values per requested column, in request order; each of length N (rows).
    pub columns: Vec<Option<Vec<f64>>>,
}

/// Reads a log into a validated [`Experiment`] with one channel per entry of
/// `spec.columns` (optional ones only when present).
///
/// Gzip is detected by the magic bytes `1f 8b`, not by the extension; a Parquet or Arrow
/// IPC file (by extension, [`super::columnar::Format`]) is read the same way, its columns
/// by name ([`super::columnar::read_table`]). Fields may be
/// surrounded by blanks; `nan` and `inf` parse as numbers and are then rejected by
/// validation, naming the column. The sample time h \[s\] is the mean step of the time
/// column, which must be uniform ([`Experiment::try_from_time`]). No plausibility limit
/// applies to h here (a thermal log may be sampled every minute); `spec.limits` bound the
/// file ([`ReadLimits`]). The path `-` reads standard input.
///
/// # Errors
/// Those of [`read_table`] (which stops at the first NaN/Inf or bad time step) or of
/// [`super::columnar::read_table`], and of
/// [`Experiment::try_from_time`] with the column names of the file in
/// [`Error::NonFinite`]; [`Error::InvalidOption`] for a non-finite or zero scale, or a
/// time scale that is not positive (the time column is checked as written).
pub fn read_csv(path: impl AsRef<Path>, spec: &CsvSpec) -> Result<Experiment> {
    let path = path.as_ref();
    for (what, s) in std::iter::once(("time_scale", spec.time_scale))
        .chain(spec.columns.iter().map(|c| (c.column.as_str(), c.scale)))
    {
        if !(s.is_finite() && s != 0.0) {
            return Err(Error::InvalidOption {
                option: format!("scale of `{what}`"),
                reason: format!("must be finite and non-zero, got {s}"),
            });
        }
    }
    if spec.time_scale < 0.0 {
        return Err(Error::InvalidOption {
            option: "time_scale".into(),
            reason: format!("must be positive, got {}", spec.time_scale),
        });
    }
    let mut wanted = vec![(spec.time.as_str(), true)];
    wanted.extend(spec.columns.iter().map(|c| (c.column.as_str(), c.required)));
    let table = super::columnar::read_table(path, &wanted, &spec.limits, spec.delimiter)?;
    let mut cols = table.columns.into_iter();
    let mut t = cols.next().flatten().unwrap_or_default();
    t.iter_mut().for_each(|v| *v *= spec.time_scale);
    let channels = spec
        .columns
        .iter()
        .zip(cols)
        .filter_map(|(c, v)| {
            let mut v = v?;
            if c.scale != 1.0 {
                v.iter_mut().for_each(|x| *x *= c.scale);
            }
            Some(Channel::new(c.channel.clone(), c.unit.clone(), v))
        })
        .collect();
    Experiment::try_from_time(table.name, &spec.time, &t, channels).map_err(|e| match e {
        Error::NonFinite { column, row, value } => {
            let column =
                spec.columns.iter().find(|c| c.channel == column).map_or(column, |c| c.column.clone());
            Error::NonFinite { column, row, value }
        }
        other => other,
    })
}

/// Reads several logs with [`read_csv`], in parallel, keeping the order of `paths`.
///
/// # Errors
/// The first error, in the order of `paths`, that [`read_csv`] returns for any of them.
pub fn read_csv_many<P: AsRef<Path> + Sync>(paths: &[P], spec: &CsvSpec) -> Result<Vec<Experiment>> {
    let results: Vec<Result<Experiment>> = paths.par_iter().map(|p| read_csv(p, spec)).collect();
    results.into_iter().collect()
}

/// Parses the columns `wanted` (`(header name, required)`) of a CSV file, plain or gzip,
/// its fields separated by `delimiter`; the first is the time column `t_k`, checked as it
/// streams ([`read_table_with`] and [`TimeCheck::Skip`] leave that check to the caller).
///
/// A second thread reads (and gunzips) the file in line-aligned chunks of 256 KiB while
/// the caller parses; chunks without a `"` are parsed in parallel batches (fields split at
/// the delimiter and trimmed, numbers accepted and valued as `str::parse::<f64>` does, bit
/// for bit, through `fast-float2` for plain decimals; an unwanted field is skipped, not
/// parsed) and merged in order, and from the first chunk with a
/// `"` on the `csv` parser takes over, so quoted fields, `""` escapes and line breaks in
/// quotes read as the `csv` crate reads them. Either way, each row is checked in order as
/// it is merged: a wanted field must be a finite number and the time column must pass
/// [`TimeSteps::push`](super::TimeSteps::push) (positive steps, none far from the mean so
/// far). So the read stops at the first bad row (a chunk's too-long line is found before
/// its rows are parsed, as by a streaming reader that bounds lines before it parses them)
/// and its memory is the wanted columns of the rows accepted, plus 32 chunks (8 MiB read
/// ahead or being parsed, their buffers reused) and one line. The columns are reserved
/// for the rows the file's size predicts (for gzip the size it records, believed only up
/// to 32 times the stored file), so that they grow about once instead of doubling; the
/// capacity not yet filled is address space, not memory in use.
/// Errors quote at most [`QUOTE_CHARS`] characters of a cell. Unwanted columns may hold
/// anything, even share a name: their cells are skipped (delimiters counted), never parsed.
///
/// # Errors
/// - [`Error::Io`] with the path if the file cannot be opened, read or decompressed;
/// - [`Error::LimitExceeded`] naming the line where a line's length, the header's field
///   count or the number of rows passes `limits`;
/// - [`Error::TooShort`] for an empty file or a header without any name;
/// - [`Error::Csv`] (line of the header) for a header of one field that holds another of
///   the [`Delimiter`]s while a required column is missing: the message names that
///   delimiter (`read the file with the delimiter `;` (`--delimiter ';'`)`);
/// - [`Error::DuplicateColumn`] for a wanted name that appears twice in the header, with
///   both 1-based positions;
/// - [`Error::MissingColumn`] naming the first required column not in the header and
///   listing the header;
/// - [`Error::Csv`] with the path and 1-based line number for a row whose field count
///   differs from the header's, or a needed field that is not a number (naming the column
///   and the text found);
/// - [`Error::NonFinite`] naming the header column and 0-based data row of a NaN/Inf in a
///   wanted column; [`Error::NonUniformTime`] for a non-increasing or grossly irregular
///   time step.
///
/// Never panics.
pub fn read_table(
    path: impl AsRef<Path>,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    delimiter: Delimiter,
) -> Result<Table> {
    read_table_with(path, wanted, limits, delimiter, TimeCheck::Streaming)
}

/// [`read_table`], with `time` saying whether the time column (the first of `wanted`) is
/// checked as the rows stream in ([`TimeCheck::Streaming`], what [`read_table`] does) or
/// read as any other wanted column, its steps left to the caller ([`TimeCheck::Skip`]).
///
/// # Errors
/// Those of [`read_table`]; with [`TimeCheck::Skip`] never [`Error::NonUniformTime`], and a
/// NaN/Inf in the time column is [`Error::NonFinite`] naming it as for any wanted column.
///
/// Never panics.
pub fn read_table_with(
    path: impl AsRef<Path>,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    delimiter: Delimiter,
    time: TimeCheck,
) -> Result<Table> {
    table::read(path.as_ref(), wanted, limits, delimiter, time)
}

/// Positions in `header` of the `wanted` columns (`(name, required)`), `None` for an
/// absent optional one: the header checks of [`read_table`], shared by the columnar reader.
///
/// # Errors
/// [`Error::LimitExceeded`] (line 1) for more than `limits.max_fields` names,
/// [`Error::TooShort`] for a header without any name, [`Error::DuplicateColumn`] for a
/// wanted name found twice, [`Error::MissingColumn`] for a required one not found.
pub(crate) fn find_columns(
    path: &Path,
    header: &[String],
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
) -> Result<Vec<Option<usize>>> {
    if header.len() > limits.max_fields {
        return Err(Error::LimitExceeded {
            path: path.to_path_buf(),
            line: 1,
            what: format!("a header of {} fields", header.len()),
            limit: "max_fields".into(),
            max: limits.max_fields as u64,
        });
    }
    if header.iter().all(String::is_empty) {
        return Err(Error::TooShort { name: experiment_name(path), len: 0, min: 1 });
    }
    let mut index = Vec::with_capacity(wanted.len());
    for &(column, required) in wanted {
        let mut found = header.iter().enumerate().filter(|(_, h)| *h == column).map(|(i, _)| i);
        let first = found.next();
        if let (Some(first), Some(second)) = (first, found.next()) {
            return Err(Error::DuplicateColumn {
                path: path.to_path_buf(),
                column: column.to_string(),
                first: first + 1,
                second: second + 1,
            });
        }
        if first.is_none() && required {
            return Err(Error::MissingColumn {
                path: path.to_path_buf(),
                column: column.to_string(),
                available: header.iter().map(|h| name_excerpt(h.as_bytes())).collect::<Vec<_>>().join(", "),
            });
        }
        index.push(first);
    }
    Ok(index)
}

/// A cell for an error message: in backquotes, cut after [`QUOTE_CHARS`] characters with
/// `…` and the cell's full length in bytes.
pub(crate) fn quote(field: &[u8]) -> String {
    match excerpt(field) {
        (head, Some(len)) => format!("`{head}…` ({len} bytes)"),
        (head, None) => format!("`{head}`"),
    }
}

/// A header name for the list of columns in [`Error::MissingColumn`]: as [`quote`],
/// without the backquotes.
pub(crate) fn name_excerpt(field: &[u8]) -> String {
    match excerpt(field) {
        (head, Some(len)) => format!("{head}… ({len} bytes)"),
        (head, None) => head,
    }
}

/// The first [`QUOTE_CHARS`] characters of `field`, and its length in bytes when cut.
fn excerpt(field: &[u8]) -> (String, Option<usize>) {
    // Only the excerpt is decoded, never the whole (possibly huge) cell.
    let max = 4 * QUOTE_CHARS;
    let head = String::from_utf8_lossy(&field[..field.len().min(max)]);
    match head.char_indices().nth(QUOTE_CHARS) {
        Some((cut, _)) => (head[..cut].to_string(), Some(field.len())),
        None if field.len() > max => (head.into_owned(), Some(field.len())),
        None => (head.into_owned(), None),
    }
}

fn csv_error(path: &Path, e: csv::Error) -> Error {
    let line = e.position().map_or(0, |p| p.line());
    match e.into_kind() {
        csv::ErrorKind::Io(source) => {
            if let Some(long) = source.get_ref().and_then(|e| e.downcast_ref::<LineTooLong>()) {
                return Error::LimitExceeded {
                    path: path.to_path_buf(),
                    line: long.line,
                    what: format!("a line (record) longer than {} bytes", long.max),
                    limit: "max_line_bytes".into(),
                    max: long.max,
                };
            }
            Error::Io { path: path.to_path_buf(), source }
        }
        csv::ErrorKind::UnequalLengths { expected_len, len, .. } => Error::Csv {
            path: path.to_path_buf(),
            line,
            message: format!("row has {len} fields, the header has {expected_len}"),
        },
        other => Error::Csv { path: path.to_path_buf(), line, message: format!("{other:?}") },
    }
}

/// File name without `.gz` and then without its extension (`.csv`); `stdin` for `-`.
pub(crate) fn experiment_name(path: &Path) -> String {
    if path == Path::new("-") {
        return "stdin".into();
    }
    let file = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let file = file.strip_suffix(".gz").unwrap_or(&file);
    let stem = Path::new(file).file_stem().map(|s| s.to_string_lossy().into_owned());
    stem.unwrap_or_else(|| file.to_string())
}
