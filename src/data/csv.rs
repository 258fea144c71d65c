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

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Channel, Experiment};
use crate::error::{Error, Result};

/// One column read into one channel: `channel = scale × column` [unit].
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
}

impl Default for CsvSpec {
    fn default() -> Self {
        Self { time: "t".into(), time_scale: 1.0, columns: Vec::new() }
    }
}

/// Columns parsed from a file: one entry per requested column, `None` when an optional
/// column is absent.
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
/// Gzip is detected by the magic bytes `1f 8b`, not by the extension. Fields may be
/// surrounded by blanks; `nan` and `inf` parse as numbers and are then rejected by
/// validation, naming the column. The sample time h [s] is the mean step of the time
/// column, which must be uniform ([`Experiment::try_from_time`]).
///
/// # Errors
/// Those of [`read_table`], and of [`Experiment::try_from_time`] with the column names
/// of the file in [`Error::NonFinite`]; [`Error::InvalidOption`] for a non-finite or zero
/// scale.
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
    let mut wanted = vec![(spec.time.as_str(), true)];
    wanted.extend(spec.columns.iter().map(|c| (c.column.as_str(), c.required)));
    let table = read_table(path, &wanted)?;
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

/// Parses the columns `wanted` (`(header name, required)`) of a CSV file, plain or gzip.
///
/// # Errors
/// - [`Error::Io`] with the path if the file cannot be opened, read or decompressed;
/// - [`Error::TooShort`] for an empty file or a header without any name;
/// - [`Error::MissingColumn`] naming the first required column not in the header and
///   listing the header;
/// - [`Error::Csv`] with the path and 1-based line number for a row whose field count
///   differs from the header's, or a needed field that is not a number (naming the column
///   and the text found).
///
/// Never panics.
pub fn read_table(path: impl AsRef<Path>, wanted: &[(&str, bool)]) -> Result<Table> {
    let path = path.as_ref();
    let name = experiment_name(path);
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
        return Err(Error::TooShort { name, len: 0, min: 1 });
    }
    let mut index = Vec::with_capacity(wanted.len());
    for &(column, required) in wanted {
        let found = header.iter().position(|h| h == column);
        if found.is_none() && required {
            return Err(Error::MissingColumn {
                path: path.to_path_buf(),
                column: column.to_string(),
                available: header.join(", "),
            });
        }
        index.push(found);
    }
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); wanted.len()];
    let mut record = csv::ByteRecord::new();
    let mut row = 0usize;
    while rdr.read_byte_record(&mut record).map_err(|e| csv_error(path, e))? {
        for (column, idx) in values.iter_mut().zip(&index) {
            let Some(idx) = *idx else { continue };
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
    if row == 0 {
        return Err(Error::TooShort { name, len: 0, min: 1 });
    }
    let columns = values.into_iter().zip(&index).map(|(v, i)| i.map(|_| v)).collect();
    Ok(Table { name, header, columns })
}

fn parse_f64(field: &[u8]) -> Option<f64> {
    std::str::from_utf8(field).ok()?.parse::<f64>().ok()
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
