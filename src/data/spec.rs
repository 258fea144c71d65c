//! How a log's columns become an [`Experiment`]'s channels ([`CsvSpec`], [`ColumnMap`]: names,
//! units, scales), and the reader that applies it to a log in any format ([`read_csv`]).

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::channel::Channel;
use super::delimiter::Delimiter;
use super::experiment::Experiment;
use super::format::read_table;
use super::table::ReadLimits;
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

/// Reads a log into a validated [`Experiment`] with one channel per entry of
/// `spec.columns` (optional ones only when present).
///
/// Gzip is detected by the magic bytes `1f 8b`, not by the extension; a Parquet or Arrow
/// IPC file (by extension, [`super::format::Format`]) is read the same way, its columns
/// by name ([`super::format::read_table`]). Fields may be
/// surrounded by blanks; `nan` and `inf` parse as numbers and are then rejected by
/// validation, naming the column. The sample time h \[s\] is the mean step of the time
/// column, which must be uniform ([`Experiment::try_from_time`]). No plausibility limit
/// applies to h here (a thermal log may be sampled every minute); `spec.limits` bound the
/// file ([`ReadLimits`]). The path `-` reads standard input.
///
/// ```no_run
/// use greybox::data::{read_csv, ColumnMap, CsvSpec};
/// let spec = CsvSpec {
///     columns: vec![ColumnMap::new("p_cu", "p_cu", "W"), ColumnMap::new("temp", "T_w", "K")],
///     ..Default::default()
/// };
/// let e = read_csv("winding.csv", &spec)?;
/// println!("{} samples every {} s", e.len(), e.h());
/// # Ok::<(), greybox::Error>(())
/// ```
///
/// # Errors
/// Those of [`read_table`] (a CSV log: [`super::csv::read_table_with`], which stops at the first NaN/Inf or
/// bad time step), and of
/// [`Experiment::try_from_time`] with the column names of the file in
/// [`Error::NonFinite`]; [`Error::InvalidOption`] for a non-finite or zero scale, or a
/// time scale that is not positive (the time column is checked as written).
pub fn read_csv(path: impl AsRef<Path>, spec: &CsvSpec) -> Result<Experiment> {
    let wanted = wanted(spec)?;
    experiment(read_table(path.as_ref(), &wanted, &spec.limits, spec.delimiter)?, spec)
}

/// [`read_csv`] for Arrow record `batches` in memory with `schema` (feature `parquet`): the
/// same columns, scales, units and checks as a columnar file's, `name` standing for the
/// file's path in errors and naming the experiment.
///
/// # Errors
/// Those of [`read_csv`] for a columnar file but [`Error::Io`], each naming `name`.
#[cfg(feature = "parquet")]
pub fn read_spec_batches(
    name: &str,
    schema: &arrow_schema::Schema,
    batches: &[arrow_array::RecordBatch],
    spec: &CsvSpec,
) -> Result<Experiment> {
    let wanted = wanted(spec)?;
    let time = super::time::TimeCheck::Streaming;
    experiment(super::format::read_batches_with(name, schema, batches, &wanted, &spec.limits, time)?, spec)
}

/// The columns `spec` reads (the time first, then each column and whether it is
/// required), its scales checked.
///
/// # Errors
/// [`Error::InvalidOption`] for a non-finite or zero scale, or a time scale that is not
/// positive.
fn wanted(spec: &CsvSpec) -> Result<Vec<(&str, bool)>> {
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
    Ok(wanted)
}

/// The experiment of `table` (read with [`wanted`]`(spec)`): the time and each present
/// column scaled into its channel.
///
/// # Errors
/// Those of [`Experiment::try_from_time`], a non-finite value named by its column.
fn experiment(table: super::table::Table, spec: &CsvSpec) -> Result<Experiment> {
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
