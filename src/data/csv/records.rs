//! The records of a CSV log through `csv-core`, the `csv` crate's parser: quoted fields,
//! `""` escapes, line breaks in quotes, CR, LF and CRLF, blank lines skipped; fields are
//! trimmed of ASCII whitespace, each record checked against the header and its wanted
//! fields parsed. A record's line is the `csv` crate's: one plus the `\n` up to the line
//! break that ended the record before (blank lines before it, the `\n` of a CRLF and the
//! line breaks of a multi-line record do not move it).

use csv_core::{ReadRecordResult, Reader, ReaderBuilder};

use crate::data::table::quote;

/// The line of a record, relative to the start of its parser's input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Line {
    /// The parser's first record: its line continues the count of the records before it,
    /// known only in order.
    First,
    /// `n` = `\n` from the parser's start up to the line break that ended the record before.
    After(u64),
}

/// The first error of a parse; rows count from the parse's first record.
#[derive(Debug)]
pub(super) enum RecordError {
    /// A record whose field count differs from the header's.
    Fields { line: Line, len: usize },
    /// A record beyond the row cap.
    RowLimit { line: Line },
    /// A wanted field that is not a number; `cell` is its quoted excerpt.
    Number { line: Line, row: usize, idx: usize, cell: String },
    /// A wanted field that is NaN or ±Inf.
    NonFinite { row: usize, idx: usize, value: f64 },
}

/// The records of one parse.
#[derive(Debug)]
pub(super) struct Parsed {
    /// Values per wanted column (empty for absent ones). On error the row of the error
    /// holds the values parsed before it, so the time column may be one row longer.
    pub columns: Vec<Vec<f64>>,
    /// Records accepted.
    pub rows: usize,
    /// The parser's `\n` up to the line break that ended its last record, if any.
    pub last_break: Option<u64>,
    /// The first error.
    pub error: Option<RecordError>,
}

/// Where a record's wanted fields are: the header's field count and each wanted column's
/// position in the header (`None` when absent).
pub(super) struct Layout<'a> {
    pub fields: usize,
    pub index: &'a [Option<usize>],
    /// Whether an empty or non-finite wanted field reads as NaN instead of an error.
    pub missing: bool,
}

/// A `csv-core` parser fed input piece by piece, and its last record.
pub(super) struct Records {
    core: Reader,
    out: Vec<u8>,
    ends: Vec<usize>,
    /// Bytes and field ends of the record being read.
    nout: usize,
    nend: usize,
    /// Fields of the last record.
    len: usize,
    /// `\n` up to the line break that ended the last record, `None` before the first.
    pub last_break: Option<u64>,
    /// Nothing read yet.
    fresh: bool,
}

impl Records {
    /// A parser of fields split at `delimiter`, whose input does not start the file (a byte
    /// order mark there is data: the caller drops the file's own).
    pub(super) fn new(delimiter: u8) -> Self {
        let core = ReaderBuilder::new().delimiter(delimiter).build();
        let (out, ends) = (vec![0; 1 << 12], vec![0; 64]);
        Self { core, out, ends, nout: 0, nend: 0, len: 0, last_break: None, fresh: true }
    }

    /// The parser, ready for input that starts a record (not the file's start).
    pub(super) fn reset(&mut self) -> &mut Self {
        self.core.reset();
        (self.nout, self.nend, self.len, self.last_break, self.fresh) = (0, 0, 0, None, true);
        self
    }

    /// Reads the next record from `input[*pos..]`, a record that the input before began
    /// continued: its line (its fields then through [`Records::field`]), or `None` when the
    /// input is used up (with `eof`, the data's end: the last record then ends with it).
    pub(super) fn next(&mut self, input: &[u8], pos: &mut usize, eof: bool) -> Option<Line> {
        loop {
            let mut rest = &input[*pos..];
            if rest.is_empty() && !eof {
                return None;
            }
            if self.fresh {
                // `csv-core` drops a byte order mark only from a first read of 3 bytes or more.
                rest = &rest[..rest.len().min(1)];
                self.fresh = false;
            }
            let (res, nin, nout, nend) =
                self.core.read_record(rest, &mut self.out[self.nout..], &mut self.ends[self.nend..]);
            (*pos, self.nout, self.nend) = (*pos + nin, self.nout + nout, self.nend + nend);
            match res {
                ReadRecordResult::InputEmpty => {}
                ReadRecordResult::OutputFull => self.out.resize(2 * self.out.len(), 0),
                ReadRecordResult::OutputEndsFull => self.ends.resize(2 * self.ends.len(), 0),
                ReadRecordResult::Record => {
                    let line = self.last_break.map_or(Line::First, Line::After);
                    self.last_break = Some(self.core.line() - 1);
                    (self.len, self.nout, self.nend) = (self.nend, 0, 0);
                    return Some(line);
                }
                ReadRecordResult::End => return None,
            }
        }
    }

    /// Field `i` of the last record, trimmed of ASCII whitespace.
    pub(super) fn field(&self, i: usize) -> &[u8] {
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        self.out[start..self.ends[i]].trim_ascii()
    }

    /// The fields of the last record.
    pub(super) fn fields(&self) -> impl Iterator<Item = &[u8]> {
        (0..self.len).map(|i| self.field(i))
    }

    /// Checks the last record (its `row` of the parse) and pushes its wanted values, in the
    /// order of the wanted columns: the first error the `csv`-based reader met.
    fn check(
        &self,
        line: Line,
        layout: &Layout,
        row: usize,
        cap: usize,
        columns: &mut [Vec<f64>],
    ) -> Option<RecordError> {
        if self.len != layout.fields {
            return Some(RecordError::Fields { line, len: self.len });
        }
        if row >= cap {
            return Some(RecordError::RowLimit { line });
        }
        for (column, idx) in columns.iter_mut().zip(layout.index) {
            let Some(idx) = *idx else { continue };
            let field = self.field(idx);
            let x = match parse_f64(field) {
                Some(x) => x,
                None if layout.missing && field.is_empty() => f64::NAN,
                None => return Some(RecordError::Number { line, row, idx, cell: quote(field) }),
            };
            if !x.is_finite() && !layout.missing {
                return Some(RecordError::NonFinite { row, idx, value: x });
            }
            column.push(x);
        }
        None
    }
}

/// Parses the records of `input` with `rec` (`eof`: the data ends with it), at most `cap`
/// of them, into the wanted columns of `layout`, stopping at the first error.
pub(super) fn parse(rec: &mut Records, input: &[u8], eof: bool, layout: &Layout, cap: usize) -> Parsed {
    let columns = vec![Vec::with_capacity(input.len() / 64); layout.index.len()];
    let mut p = Parsed { columns, rows: 0, last_break: None, error: None };
    let mut pos = 0;
    while let Some(line) = rec.next(input, &mut pos, eof) {
        p.error = rec.check(line, layout, p.rows, cap, &mut p.columns);
        if p.error.is_some() {
            break;
        }
        p.rows += 1;
    }
    p.last_break = rec.last_break;
    p
}

/// Parses a whole (already trimmed) field as [`str::parse::<f64>`] does: the same accepted
/// texts and the same value, bit for bit. `fast_float2` takes the field first: like the
/// standard library it rounds correctly, and its decimal grammar
/// (`[+-]digits[.digits][(e|E)[+-]digits]`, nothing after) is the standard library's, so a
/// finite value from it is the standard library's value. Anything else (`nan`, `inf`, an
/// overflow to ±Inf, junk, invalid UTF-8) takes the standard parser. Tests in
/// `tests/it/csv_reader.rs` compare the two on edge cases and random texts.
fn parse_f64(field: &[u8]) -> Option<f64> {
    match fast_float2::parse::<f64, _>(field) {
        Ok(x) if x.is_finite() => Some(x),
        _ => std::str::from_utf8(field).ok()?.parse::<f64>().ok(),
    }
}
