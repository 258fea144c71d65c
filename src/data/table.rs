//! What every log reader shares, whatever the format: the read's bounds ([`ReadLimits`]),
//! its result ([`Table`]), the header checks ([`find_columns`]), the experiment's name
//! from the path, and the excerpts of cells and names that errors quote.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

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

/// Positions in `header` of the `wanted` columns (`(name, required)`), `None` for an
/// absent optional one: the header checks of every reader ([`super::csv::read_table_with`], the columnar one).
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
