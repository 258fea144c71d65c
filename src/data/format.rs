//! The format of a log, by its file's extension, and the readers and writer that dispatch
//! on it: CSV ([`super::csv`]) or columnar, Parquet and Arrow IPC ([`super::columnar`]).
//!
//! ```no_run
//! use greybox::pmsm::{read_log, CsvOptions};
//! // The same options as for a CSV log: column names, units, frames.
//! let exp = read_log("log.parquet", &CsvOptions::default())?;
//! greybox::data::write_log("copy.arrow".as_ref(), &exp, "t")?;
//! # Ok::<(), greybox::Error>(())
//! ```

use std::path::Path;

use super::delimiter::Delimiter;
use super::experiment::Experiment;
use super::table::{ReadLimits, Table};
use super::time::TimeCheck;
// Without the feature only `without_feature` builds an error; the docs link it either way.
#[cfg_attr(feature = "parquet", allow(unused_imports))]
use crate::error::Error;
use crate::error::Result;

/// File formats of a log, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// CSV, plain or gzip (any extension not listed below).
    Csv,
    /// Apache Parquet: `.parquet`, `.pq`.
    Parquet,
    /// Arrow IPC file (Feather v2) or stream: `.arrow`, `.feather`, `.ipc`, `.arrows`.
    ArrowIpc,
}

impl Format {
    /// The format of `path`, from its extension (case-insensitive); CSV for any other.
    pub fn of(path: &Path) -> Self {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("parquet" | "pq") => Self::Parquet,
            Some("arrow" | "feather" | "ipc" | "arrows") => Self::ArrowIpc,
            _ => Self::Csv,
        }
    }

    /// Whether this build reads and writes the format (CSV always; the columnar ones with
    /// the cargo feature `parquet`).
    pub fn available(self) -> bool {
        self == Self::Csv || cfg!(feature = "parquet")
    }
}

/// Parses the columns `wanted` (`(header name, required)`, the first the time column) of a
/// log in any [`Format`], by extension: a CSV file through
/// [`crate::data::csv::read_table_with`] with its fields separated by `delimiter`, a columnar one through the Arrow readers (only the
/// wanted columns are decoded; Parquet row groups in parallel).
///
/// # Errors
/// For CSV those of [`crate::data::csv::read_table_with`]. For a columnar file:
/// [`Error::Format`] when the build lacks the feature `parquet`, for a file that is not
/// valid Parquet/Arrow IPC, or for a null in a wanted column (naming it and the row);
/// [`Error::Io`] when it cannot be opened; [`Error::LimitExceeded`] for more columns than
/// `limits.max_fields` or more rows than `limits.max_rows`; [`Error::TooShort`],
/// [`Error::DuplicateColumn`], [`Error::MissingColumn`] as for CSV; [`Error::ColumnType`]
/// naming a wanted column that is not numeric; [`Error::NonFinite`] naming the column and
/// 0-based row of the first NaN/Inf; [`Error::NonUniformTime`] for a bad time step.
pub fn read_table(
    path: impl AsRef<Path>,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    delimiter: Delimiter,
) -> Result<Table> {
    read_table_with(path, wanted, limits, delimiter, TimeCheck::Streaming)
}

/// [`read_table`], with `time` saying whether the time column (the first of `wanted`) is
/// checked with [`crate::data::TimeSteps`] in row order ([`TimeCheck::Streaming`], what
/// [`read_table`] does) or read as any other wanted column, its steps left to the caller
/// ([`TimeCheck::Skip`]); a CSV file through [`crate::data::csv::read_table_with`].
///
/// # Errors
/// Those of [`read_table`]; with [`TimeCheck::Skip`] never [`Error::NonUniformTime`], and a
/// NaN/Inf in the time column is [`Error::NonFinite`] naming it as for any wanted column.
pub fn read_table_with(
    path: impl AsRef<Path>,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    delimiter: Delimiter,
    time: TimeCheck,
) -> Result<Table> {
    let path = path.as_ref();
    match Format::of(path) {
        Format::Csv => super::csv::read_table_with(path, wanted, limits, delimiter, time),
        #[cfg(feature = "parquet")]
        format => super::columnar::arrow_io::read(path, format == Format::Parquet, wanted, limits, time),
        #[cfg(not(feature = "parquet"))]
        format => Err(without_feature(path, format)),
    }
}

/// [`read_table_with`] for Arrow record `batches` in memory with `schema` (feature
/// `parquet`): the wanted columns converted to f64 under the same checks as a columnar
/// file's, `name` standing for the file's path in errors and naming the [`Table`].
///
/// # Errors
/// Those of [`read_table_with`] for a columnar file but [`Error::Io`], each naming `name`.
#[cfg(feature = "parquet")]
pub fn read_batches_with(
    name: &str,
    schema: &arrow_schema::Schema,
    batches: &[arrow_array::RecordBatch],
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    time: TimeCheck,
) -> Result<Table> {
    super::columnar::memory::read_batches(name, schema, batches, wanted, limits, time)
}

/// The experiment `e` as one Arrow record batch (feature `parquet`): a time column `time`
/// \[s\] (`t_k = k h`) and every channel in order, all f64 of length N, each field's unit in
/// its metadata (`unit`); what [`write()`] puts in a Parquet or Arrow file.
///
/// # Errors
/// [`Error::Format`] (path `memory`) if Arrow refuses the columns (it does not for a valid
/// experiment).
#[cfg(feature = "parquet")]
pub fn to_record_batch(e: &Experiment, time: &str) -> Result<arrow_array::RecordBatch> {
    super::columnar::arrow_io::batch(e, time)
        .map_err(|err| Error::Format { path: "memory".into(), message: err.to_string() })
}

/// Writes `e` to `path` in the [`Format`] of its extension, atomically
/// ([`crate::data::write_atomic`]): a time column `time` \[s\] (`t_k = k h`) and every
/// channel in order, all f64, so that [`read_table`] reads back the same values bit for
/// bit. CSV as [`crate::data::write_csv`]; Parquet with Snappy-compressed pages
/// and row groups of 65 536 rows, each channel's unit in its field metadata (`unit`);
/// Arrow IPC as an uncompressed file.
///
/// # Errors
/// [`Error::Write`] with the path; [`Error::Format`] when the build lacks the feature
/// `parquet`.
pub fn write(path: &Path, e: &Experiment, time: &str) -> Result<()> {
    match Format::of(path) {
        Format::Csv => super::write::write_csv(path, e, time),
        #[cfg(feature = "parquet")]
        format => super::columnar::arrow_io::write(path, format == Format::Parquet, e, time),
        #[cfg(not(feature = "parquet"))]
        format => Err(without_feature(path, format)),
    }
}

#[cfg(not(feature = "parquet"))]
fn without_feature(path: &Path, format: Format) -> Error {
    Error::Format {
        path: path.to_path_buf(),
        message: format!(
            "{format:?} files need greybox built with the cargo feature `parquet` (on with the default \
             `cli` feature; this build has it off)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_by_extension() {
        for (name, f) in [
            ("a.parquet", Format::Parquet),
            ("a.PQ", Format::Parquet),
            ("a.arrow", Format::ArrowIpc),
            ("a.feather", Format::ArrowIpc),
            ("a.ipc", Format::ArrowIpc),
            ("a.csv.gz", Format::Csv),
            ("a", Format::Csv),
        ] {
            assert_eq!(Format::of(Path::new(name)), f, "{name}");
        }
    }

    /// `cargo test --no-default-features --lib`: a columnar path names the missing feature.
    #[cfg(not(feature = "parquet"))]
    #[test]
    fn without_the_feature_a_columnar_file_names_it() {
        let path = std::env::temp_dir().join(format!("greybox-nofeature-{}.parquet", std::process::id()));
        std::fs::write(&path, b"PAR1").unwrap();
        let err = read_table(&path, &[("t", true)], &ReadLimits::default(), Delimiter::COMMA).unwrap_err();
        assert!(matches!(err, Error::Format { .. }) && err.to_string().contains("`parquet`"), "{err}");
        std::fs::remove_file(&path).ok();
        assert!(!Format::Parquet.available() && Format::Csv.available());
    }
}
