//! CSV logs, plain or gzip-compressed: the reader of their columns ([`read_table_with`]), on
//! `csv-core`, the `csv` crate's parser. A log is a CSV file with a header line and one row
//! per sample `t_k = k h`; only the wanted columns are parsed, the others may hold anything.
//!
//! The reader of a log into channels, in any format ([`read_csv`](super::read_csv), its [`CsvSpec`](super::CsvSpec)), and the
//! types every reader shares ([`Table`], [`ReadLimits`], [`Delimiter`]) live beside this
//! module and are re-exported here. Domain readers (the PMSM log reader
//! [`crate::pmsm::read_log`]) build on [`crate::data::read_table`].

use std::path::Path;

use super::delimiter::Delimiter;
pub(crate) use super::table::name_excerpt;
use super::table::{ReadLimits, Table};
use super::time::TimeCheck;
use crate::error::Result;

mod read;
mod records;

/// Parses the columns `wanted` (`(header name, required)`) of a CSV file, plain or gzip,
/// its fields separated by `delimiter`; the first is the time column `t_k`, checked as it
/// streams with [`TimeCheck::Streaming`], or read as any other wanted column with
/// [`TimeCheck::Skip`] (its steps left to the caller, and a NaN/Inf in it then an
/// [`Error::NonFinite`](crate::Error::NonFinite) as for any wanted column).
///
/// Records and fields are the `csv` crate's (quoted fields, `""` escapes, line breaks in
/// quotes; CR, LF or CRLF; blank lines skipped; a byte order mark dropped), fields trimmed
/// of ASCII whitespace; a wanted field must be a number as `str::parse::<f64>` reads it,
/// valued bit for bit as it does. A second thread reads (and gunzips) the file in
/// line-aligned chunks of 256 KiB; chunks without a `"` are parsed in parallel batches,
/// from the first `"` on in order. Each row is checked in order as it is merged: finite
/// wanted values, and a time column that passes
/// [`TimeSteps::push`](super::TimeSteps::push). So the read stops at the first bad row (a
/// chunk's too-long line is found before its rows are parsed, as by a streaming reader that
/// bounds lines first), and its memory is the wanted columns of the rows accepted, reserved
/// for the rows the file's size predicts, plus 32 chunks (8 MiB) and one line. Errors quote
/// at most [`QUOTE_CHARS`](super::QUOTE_CHARS) characters of a cell.
///
/// # Errors
/// - [`Error::Io`](crate::Error::Io) with the path if the file cannot be opened, read or
///   decompressed;
/// - [`Error::LimitExceeded`](crate::Error::LimitExceeded) naming the line where a line's
///   length, the header's field count or the number of rows passes `limits`;
/// - [`Error::TooShort`](crate::Error::TooShort) for an empty file or a header without any name;
/// - [`Error::Csv`](crate::Error::Csv) (line of the header) for a header of one field that
///   holds another of the [`Delimiter`]s while a required column is missing: the message
///   names that delimiter (`read the file with the delimiter `;` (`--delimiter ';'`)`);
/// - [`Error::DuplicateColumn`](crate::Error::DuplicateColumn) for a wanted name that appears
///   twice in the header, with both 1-based positions;
/// - [`Error::MissingColumn`](crate::Error::MissingColumn) naming the first required column
///   not in the header and listing the header;
/// - [`Error::Csv`](crate::Error::Csv) with the path and 1-based line number for a row whose
///   field count differs from the header's, or a wanted field that is not a number (naming
///   the column and the text found);
/// - [`Error::NonFinite`](crate::Error::NonFinite) naming the header column and 0-based data
///   row of a NaN/Inf in a wanted column;
///   [`Error::NonUniformTime`](crate::Error::NonUniformTime) for a non-increasing or grossly
///   irregular time step.
///
/// Never panics.
pub fn read_table_with(
    path: impl AsRef<Path>,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    delimiter: Delimiter,
    time: TimeCheck,
) -> Result<Table> {
    read::read(path.as_ref(), wanted, limits, delimiter, time, false)
}

/// As [`read_table_with`] with [`TimeCheck::Skip`], except that a wanted cell that is empty,
/// `nan` or ±`inf` reads as NaN instead of an error: for a table whose caller drops its
/// missing values and counts them (a measured flux map's unmeasured points).
///
/// # Errors
/// Those of [`read_table_with`] but for [`Error::NonFinite`](crate::Error::NonFinite) and
/// [`Error::NonUniformTime`](crate::Error::NonUniformTime).
pub fn read_table_with_missing(
    path: impl AsRef<Path>,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    delimiter: Delimiter,
) -> Result<Table> {
    read::read(path.as_ref(), wanted, limits, delimiter, TimeCheck::Skip, true)
}
