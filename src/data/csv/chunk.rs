//! The fast path of the CSV reader: one line-aligned chunk without any `"`, parsed on its
//! own (chunks run in parallel) into the wanted columns, with the first error it holds.
//!
//! Without quotes the `csv` parser's grammar is simple, and this follows it byte for byte:
//! a record is a non-empty run of bytes between line breaks (`\r` or `\n`; empty lines are
//! skipped), its fields are split at `,` and trimmed of ASCII whitespace. Line numbers
//! follow the `csv` crate too: a record's line is one plus the `\n` up to and including the
//! line break that ended the record before it (so blank lines before a record and the `\n`
//! of a CRLF do not count).

use super::float::parse_f64;
use super::quote;

/// Where a chunk's records sit in the table.
pub(super) struct Layout<'a> {
    /// Fields per record: the header's.
    pub fields: usize,
    /// Header position of each wanted column, `None` when absent.
    pub index: &'a [Option<usize>],
    /// Longest line in bytes.
    pub max_line: u64,
}

/// The line of a record: the first of a chunk continues the line count of the records
/// before (known only in order); the others count `\n` within the chunk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Line {
    /// The first record of the chunk.
    First,
    /// `n` = `\n` in the chunk up to the line break that ended the record before.
    After(u64),
}

/// The first error in a chunk, positions relative to it.
#[derive(Debug, PartialEq)]
pub(super) enum ChunkError {
    /// A line longer than the limit, after `newlines` `\n` in the chunk. Found before any
    /// other error of the chunk, as a streaming reader checks line lengths first.
    TooLong { newlines: u64 },
    /// A record whose field count differs from the header's.
    Fields { line: Line, len: usize },
    /// A record beyond the row cap.
    RowLimit { line: Line },
    /// A wanted field that is not a number; `cell` is its quoted excerpt.
    Number { line: Line, row: usize, idx: usize, cell: String },
    /// A wanted field that is NaN or ±Inf.
    NonFinite { row: usize, idx: usize, value: f64 },
}

/// A parsed chunk.
#[derive(Debug)]
pub(super) struct Parsed {
    /// Values per wanted column (empty for absent ones). On error the row of the error
    /// holds the values parsed before it, so the time column may be one row longer.
    pub columns: Vec<Vec<f64>>,
    /// Records accepted.
    pub rows: usize,
    /// `\n` in the chunk.
    pub newlines: u64,
    /// `\n` up to the line break that ended the chunk's last record, if it has one.
    pub last_break: Option<u64>,
    /// The first error.
    pub error: Option<ChunkError>,
}

/// Parses `chunk` (no `"` in it) with `layout`, accepting at most `cap` records.
pub(super) fn parse(chunk: &[u8], layout: &Layout, cap: usize) -> Parsed {
    let mut out = Parsed {
        columns: vec![Vec::with_capacity(chunk.len() / 64); layout.index.len()],
        rows: 0,
        newlines: 0,
        last_break: None,
        error: None,
    };
    let mut cuts = Vec::with_capacity(layout.fields);
    let mut line = Line::First;
    let mut pos = 0;
    while pos < chunk.len() {
        let end = memchr::memchr2(b'\n', b'\r', &chunk[pos..]).map_or(chunk.len(), |p| pos + p);
        let record = &chunk[pos..end];
        if record.len() as u64 > layout.max_line {
            out.error = Some(ChunkError::TooLong { newlines: out.newlines });
            return out;
        }
        if !record.is_empty() && out.error.is_none() {
            out.error = parse_record(record, line, layout, cap, &mut cuts, &mut out);
            if out.error.is_none() {
                out.rows += 1;
            }
        }
        if end < chunk.len() {
            out.newlines += u64::from(chunk[end] == b'\n');
            if !record.is_empty() {
                line = Line::After(out.newlines);
                out.last_break = Some(out.newlines);
            }
        }
        pos = end + 1;
    }
    out
}

fn parse_record(
    record: &[u8],
    line: Line,
    layout: &Layout,
    cap: usize,
    cuts: &mut Vec<usize>,
    out: &mut Parsed,
) -> Option<ChunkError> {
    cuts.clear();
    cuts.extend(memchr::memchr_iter(b',', record));
    let len = cuts.len() + 1;
    if len != layout.fields {
        return Some(ChunkError::Fields { line, len });
    }
    if out.rows >= cap {
        return Some(ChunkError::RowLimit { line });
    }
    let row = out.rows;
    for (column, idx) in out.columns.iter_mut().zip(layout.index) {
        let Some(idx) = *idx else { continue };
        let start = if idx == 0 { 0 } else { cuts[idx - 1] + 1 };
        let end = cuts.get(idx).copied().unwrap_or(record.len());
        let field = record[start..end].trim_ascii();
        let Some(x) = parse_f64(field) else {
            return Some(ChunkError::Number { line, row, idx, cell: quote(field) });
        };
        if !x.is_finite() {
            return Some(ChunkError::NonFinite { row, idx, value: x });
        }
        column.push(x);
    }
    None
}
