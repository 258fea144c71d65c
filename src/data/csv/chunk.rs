//! The fast path of the CSV reader: one line-aligned chunk without any `"`, parsed on its
//! own (chunks run in parallel) into the wanted columns, with the first error it holds.
//!
//! Without quotes the `csv` parser's grammar is simple, and this follows it byte for byte:
//! a record is a non-empty run of bytes between line breaks (`\r` or `\n`; empty lines are
//! skipped), its fields are split at the delimiter and trimmed of ASCII whitespace. Line numbers
//! follow the `csv` crate too: a record's line is one plus the `\n` up to and including the
//! line break that ended the record before it (so blank lines before a record and the `\n`
//! of a CRLF do not count).
//!
//! Each record is first read in one pass ([`fast_record`]): a wanted field is parsed where
//! it starts (the number parser finds its end), an unwanted one skipped with `memchr` to
//! the next delimiter, the delimiters counted. Only a record that pass does not accept in
//! full (a field count other than the header's, a cell that is not a finite number, the
//! row cap, a wanted column named twice) is read again the general way, which finds its
//! first error in the order the `csv`-based reader did. An unwanted cell is never parsed
//! or checked (it may hold anything, as before); only its delimiters are counted.

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
    /// The field delimiter.
    pub delimiter: u8,
    /// For each header field, the wanted column it fills ([`SKIP`] for none); empty when
    /// a field fills two (a wanted name given twice), which the one-pass read leaves to the
    /// general one.
    slots: Vec<usize>,
}

/// A header field no wanted column reads.
const SKIP: usize = usize::MAX;

impl<'a> Layout<'a> {
    /// The layout of records of `fields` fields split at `delimiter`, for the wanted
    /// columns at `index`.
    pub(super) fn new(fields: usize, index: &'a [Option<usize>], max_line: u64, delimiter: u8) -> Self {
        let mut slots = vec![SKIP; fields];
        for (slot, i) in index.iter().enumerate() {
            if let Some(i) = *i {
                match slots.get_mut(i) {
                    Some(s) if *s == SKIP => *s = slot,
                    _ => {
                        slots.clear();
                        break;
                    }
                }
            }
        }
        Self { fields, index, max_line, delimiter, slots }
    }
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
        let try_fast = !layout.slots.is_empty()
            && !matches!(chunk[pos], b'\n' | b'\r')
            && out.error.is_none()
            && out.rows < cap;
        let quick = if try_fast { fast_record(chunk, pos, layout, &mut out.columns) } else { None };
        if try_fast && quick.is_none() {
            // Values of a record the one-pass read gave up on are read again below.
            out.columns.iter_mut().for_each(|c| c.truncate(out.rows));
        }
        let end = quick
            .unwrap_or_else(|| memchr::memchr2(b'\n', b'\r', &chunk[pos..]).map_or(chunk.len(), |p| pos + p));
        let record = &chunk[pos..end];
        if record.len() as u64 > layout.max_line {
            out.error = Some(ChunkError::TooLong { newlines: out.newlines });
            return out;
        }
        if quick.is_some() {
            out.rows += 1;
        } else if !record.is_empty() && out.error.is_none() {
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

/// Reads the record starting at `start` (not at a line break) in one pass, pushing its
/// wanted values to `columns`: the position of the line break (or chunk end) that ends it
/// when it holds the header's field count and every wanted cell is a finite number, each
/// alone in its field but for blanks; `None` otherwise (some values may then be pushed).
///
/// A wanted cell's value is `fast_float2`'s, and the number it takes ends just before the
/// blanks and delimiter that end the field: so the trimmed field is exactly a number of
/// its grammar, and [`parse_f64`] would give the same value.
fn fast_record(chunk: &[u8], start: usize, layout: &Layout, columns: &mut [Vec<f64>]) -> Option<usize> {
    let d = layout.delimiter;
    // Blanks within a field: the ASCII whitespace that is neither a line break nor the delimiter.
    let blank = |b: u8| b != d && matches!(b, b' ' | b'\t' | b'\x0c');
    let n = chunk.len();
    let mut p = start;
    let mut field = 0;
    loop {
        match layout.slots.get(field) {
            Some(&slot) if slot != SKIP => {
                while p < n && blank(chunk[p]) {
                    p += 1;
                }
                let (x, len) = fast_float2::parse_partial::<f64, _>(&chunk[p..]).ok()?;
                if !x.is_finite() {
                    return None;
                }
                columns[slot].push(x);
                p += len;
                while p < n && blank(chunk[p]) {
                    p += 1;
                }
            }
            _ => p = memchr::memchr3(d, b'\n', b'\r', &chunk[p..]).map_or(n, |k| p + k),
        }
        field += 1;
        match chunk.get(p) {
            Some(&b) if b == d => p += 1,
            None | Some(b'\n' | b'\r') => break,
            Some(_) => return None,
        }
    }
    (field == layout.fields).then_some(p)
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
    cuts.extend(memchr::memchr_iter(layout.delimiter, record));
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
