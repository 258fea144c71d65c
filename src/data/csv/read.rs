//! [`read_table_with`](super::read_table_with) itself. The chunks of the file ([`source`])
//! are bounded line by line in order, then parsed: while they hold no `"`, in parallel
//! batches with a parser each (each chunk starts a record); the header, and everything from
//! the first `"` on (a quoted field may span chunks), by one parser in order. Each parsed
//! chunk is merged in order, so the first bad row stops the read.

use std::path::Path;

use rayon::prelude::*;

use super::records::{Layout, Line, Parsed, RecordError, Records, parse};
use crate::data::delimiter::Delimiter;
use crate::data::source::{self, AHEAD, Bound};
use crate::data::table::{ReadLimits, Table, experiment_name, find_columns, quote};
use crate::data::time::{TimeCheck, TimeSteps};
use crate::error::{Error, Result};

/// The parser in order, and the line its input starts on.
type Serial = Option<(Records, u64)>;

/// What the read knows at the end of the chunks merged so far.
struct State<'a> {
    path: &'a Path,
    limits: &'a ReadLimits,
    wanted: &'a [(&'a str, bool)],
    delimiter: Delimiter,
    /// The header once read, each wanted column's position in it, and its values.
    header: Option<Vec<String>>,
    index: Vec<Option<usize>>,
    values: Vec<Vec<f64>>,
    /// The streaming check of the time column; `None` for [`TimeCheck::Skip`].
    time: Option<TimeSteps>,
    /// Whether an empty or non-finite wanted cell reads as NaN (else it is an error).
    missing: bool,
    rows: usize,
    /// `\n` merged, and the line of the next record (after the break that ended the last).
    newlines: u64,
    next_line: u64,
    /// The line bound where the chunks merged end.
    bound: Bound,
    /// Bytes merged, and the file's size uncompressed and as stored (see `reserve`).
    merged_bytes: u64,
    size_hint: Option<u64>,
    stored: Option<u64>,
}

pub(super) fn read(
    path: &Path,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    delimiter: Delimiter,
    time: TimeCheck,
    missing: bool,
) -> Result<Table> {
    let mut s = State {
        path,
        limits,
        wanted,
        delimiter,
        header: None,
        index: Vec::new(),
        values: vec![Vec::new(); wanted.len()],
        time: (time == TimeCheck::Streaming).then(|| TimeSteps::new(wanted.first().map_or("", |w| w.0))),
        missing,
        rows: 0,
        newlines: 0,
        next_line: 1,
        bound: Bound::default(),
        merged_bytes: 0,
        size_hint: None,
        stored: None,
    };
    std::thread::scope(|scope| {
        let stream = source::spawn(scope, path, limits.max_line_bytes).map_err(|e| s.io(e))?;
        (s.size_hint, s.stored) = (stream.size_hint, stream.stored);
        let (mut serial, mut held, mut in_order) = (None, None, false);
        loop {
            let chunk = match held.take().map_or_else(|| stream.rx.recv(), Ok) {
                Ok(Ok(chunk)) => chunk,
                Ok(Err(e)) => return Err(s.io(e)),
                Err(_) => break,
            };
            in_order |= memchr::memchr(b'"', &chunk).is_some();
            if in_order || s.header.is_none() {
                s.serial(&mut serial, &chunk, false)?;
                if !in_order && s.header.is_some() {
                    // The header's chunk was quote-free: the next chunk starts a record.
                    s.serial(&mut serial, &[], true)?;
                    serial = None;
                }
                stream.recycle.send(chunk).ok();
                continue;
            }
            let mut batch = vec![chunk];
            while batch.len() < AHEAD {
                match stream.rx.try_recv() {
                    Ok(Ok(c)) if memchr::memchr(b'"', &c).is_none() => batch.push(c),
                    Err(_) => break,
                    item => {
                        held = item.ok();
                        break;
                    }
                }
            }
            s.batch(&batch)?;
            for chunk in batch {
                // The reading thread may have ended: then the buffer is simply dropped.
                stream.recycle.send(chunk).ok();
            }
        }
        s.serial(&mut serial, &[], true)
    })?;
    let header = match s.header {
        Some(h) if !h.iter().all(String::is_empty) && s.rows > 0 => h,
        _ => return Err(Error::TooShort { name: experiment_name(path), len: 0, min: 1 }),
    };
    let columns = s.values.into_iter().zip(&s.index).map(|(v, i)| i.map(|_| v)).collect();
    Ok(Table { name: experiment_name(path), header, columns })
}

impl State<'_> {
    fn io(&self, source: std::io::Error) -> Error {
        Error::Io { path: self.path.to_path_buf(), source }
    }

    /// Bounds `chunk`, then reads it with the parser in order (`eof`: the data ends with
    /// it), which reads the header first. Before the header, the parser starts at its first
    /// line: after a byte order mark at the file's start and blank lines (which the `csv`
    /// crate skips), counted in the header's line.
    fn serial(&mut self, serial: &mut Serial, chunk: &[u8], eof: bool) -> Result<()> {
        let max = self.limits.max_line_bytes;
        let newlines = self.bound.scan(chunk, max).map_err(|n| self.too_long(n))?;
        let mut pos = 0;
        if serial.is_none() {
            let mut base = 1 + self.newlines;
            if self.header.is_none() {
                let bom = self.newlines == 0 && self.merged_bytes == 0 && chunk.starts_with(b"\xef\xbb\xbf");
                pos = if bom { 3 } else { 0 };
                let blank = chunk[pos..].iter().take_while(|b| matches!(b, b'\n' | b'\r'));
                pos += blank.clone().count();
                self.merged_bytes += pos as u64;
                if pos == chunk.len() && !eof {
                    self.newlines += newlines;
                    return Ok(());
                }
                base += blank.filter(|&&b| b == b'\n').count() as u64;
                self.next_line = base;
            }
            *serial = Some((Records::new(self.delimiter.byte()), base));
        }
        let Some((rec, base)) = serial.as_mut() else { unreachable!("set above") };
        if self.header.is_none() {
            let Some(line) = rec.next(chunk, &mut pos, eof) else {
                self.newlines += newlines;
                return if eof { self.set_header(Vec::new(), 1) } else { Ok(()) };
            };
            let names = rec.fields().map(|f| String::from_utf8_lossy(f).into_owned()).collect();
            self.set_header(names, self.line(line, *base))?;
            self.next_line = *base + rec.last_break.unwrap_or(0);
        }
        let index = self.index.clone();
        let layout =
            Layout { fields: self.header.as_ref().map_or(0, Vec::len), index: &index, missing: self.missing };
        let p = parse(rec, &chunk[pos..], eof, &layout, self.cap());
        let base = *base;
        self.merge(chunk.len() - pos, p, base)?;
        self.newlines += newlines;
        Ok(())
    }

    /// Parses a batch of quote-free chunks, each starting a record, in parallel, and merges
    /// them in order.
    fn batch(&mut self, batch: &[Vec<u8>]) -> Result<()> {
        let index = self.index.clone();
        let layout =
            Layout { fields: self.header.as_ref().map_or(0, Vec::len), index: &index, missing: self.missing };
        let d = self.delimiter.byte();
        let parse = |rec: &mut Records, chunk: &[u8], cap| parse(rec.reset(), chunk, true, &layout, cap);
        let cap = self.cap();
        let max = self.limits.max_line_bytes;
        // Each chunk starts a line outside quotes.
        let parsed: Vec<_> = batch
            .par_iter()
            .map_init(|| Records::new(d), |rec, c| (Bound::default().scan(c, max), parse(rec, c, cap)))
            .collect();
        for (chunk, (newlines, p)) in batch.iter().zip(parsed) {
            let newlines = newlines.map_err(|n| self.too_long(n))?;
            // Parsed with a looser row cap than the rows merged since allow.
            let p = if p.rows >= self.cap() { parse(&mut Records::new(d), chunk, self.cap()) } else { p };
            self.merge(chunk.len(), p, 1 + self.newlines)?;
            self.newlines += newlines;
        }
        Ok(())
    }

    /// The line of a record that parser `base` ([`Serial`]) reports as `line`.
    fn line(&self, line: Line, base: u64) -> u64 {
        match line {
            Line::First => self.next_line,
            Line::After(n) => base + n,
        }
    }

    /// Checks the header ([`find_columns`]), found on 1-based line `line`, and keeps it.
    ///
    /// A header of one field that holds another delimiter (`t;ud;uq` read with `,`) fails
    /// with [`Error::Csv`] suggesting that delimiter, rather than as a missing column.
    fn set_header(&mut self, header: Vec<String>, line: u64) -> Result<()> {
        let index = find_columns(self.path, &header, self.wanted, self.limits);
        if let (Err(Error::MissingColumn { .. }), [only]) = (&index, header.as_slice())
            && let Some(d) =
                Delimiter::ALL.into_iter().find(|d| *d != self.delimiter && only.contains(d.byte() as char))
        {
            let message = format!(
                "the header is one field, {}, which holds `{}`: read the file with the delimiter `{d}` \
                 (`--delimiter '{d}'`), not `{}`",
                quote(only.as_bytes()),
                if d == Delimiter::TAB { "\\t" } else { d.name() },
                self.delimiter,
            );
            return Err(Error::Csv { path: self.path.to_path_buf(), line, message });
        }
        self.index = index?;
        self.header = Some(header);
        Ok(())
    }

    /// Rows still allowed by `max_rows`.
    fn cap(&self) -> usize {
        usize::try_from(self.limits.max_rows.saturating_sub(self.rows as u64)).unwrap_or(usize::MAX)
    }

    /// Appends a parse of `bytes` by parser `base`, after checking its time column row by
    /// row (unless [`TimeCheck::Skip`]); its error if any.
    fn merge(&mut self, bytes: usize, p: Parsed, base: u64) -> Result<()> {
        if let (Some(time), Some(t)) = (self.time.as_mut(), p.columns.first()) {
            t.iter().try_for_each(|&t| time.push(t))?;
        }
        let path = self.path.to_path_buf();
        let header = self.header.as_deref().unwrap_or_default();
        match p.error {
            None => {}
            Some(RecordError::Fields { line, len }) => {
                let message = format!("row has {len} fields, the header has {}", header.len());
                return Err(Error::Csv { path, line: self.line(line, base), message });
            }
            Some(RecordError::RowLimit { line }) => return Err(self.row_limit(self.line(line, base))),
            Some(RecordError::Number { line, row, idx, cell }) => {
                let (column, row) = (&header[idx], self.rows + row);
                let message = format!("column `{column}` (data row {row}): cannot parse {cell} as a number");
                return Err(Error::Csv { path, line: self.line(line, base), message });
            }
            Some(RecordError::NonFinite { row, idx, value }) => {
                return Err(Error::NonFinite { column: header[idx].clone(), row: self.rows + row, value });
            }
        }
        let need = self.rows + p.rows;
        if self.values.iter().zip(&self.index).any(|(v, i)| i.is_some() && v.capacity() < need) {
            self.reserve(bytes as u64, need);
        }
        for (v, c) in self.values.iter_mut().zip(&p.columns) {
            v.extend_from_slice(c);
        }
        self.rows += p.rows;
        self.merged_bytes += bytes as u64;
        if let Some(n) = p.last_break {
            self.next_line = base + n;
        }
        Ok(())
    }

    /// Grows the wanted columns, too short for `need` rows once `bytes` more are merged, to
    /// the rows the file's size predicts (2 % more, at least a quarter more than `need`): they
    /// grow about once instead of doubling, a tenth of the read. A hint only: never beyond
    /// `max_rows`, nor to more than 32 times the stored file (a gzip file's recorded size is
    /// anyone's word).
    fn reserve(&mut self, bytes: u64, need: usize) {
        let (Some(size), Some(stored)) = (self.size_hint, self.stored) else { return };
        let seen = self.merged_bytes + bytes;
        if seen >= size || need == 0 {
            return;
        }
        let predicted = (need as f64 * size as f64 / seen as f64 * 1.02) as u64 + 64;
        let rows = predicted.max(need as u64 + need as u64 / 4).min(self.limits.max_rows);
        let present = self.index.iter().flatten().count() as u64;
        if rows <= need as u64 || rows.saturating_mul(8 * present) > stored.saturating_mul(32) {
            return;
        }
        let rows = usize::try_from(rows).unwrap_or(need);
        for (v, i) in self.values.iter_mut().zip(&self.index) {
            if i.is_some() {
                v.reserve_exact(rows.saturating_sub(v.len()));
            }
        }
    }

    /// The error for a line too long after `newlines` more `\n` than merged.
    fn too_long(&self, newlines: u64) -> Error {
        let max = self.limits.max_line_bytes;
        Error::LimitExceeded {
            path: self.path.to_path_buf(),
            line: 1 + self.newlines + newlines,
            what: format!("a line (record) longer than {max} bytes"),
            limit: "max_line_bytes".into(),
            max,
        }
    }

    fn row_limit(&self, line: u64) -> Error {
        Error::LimitExceeded {
            path: self.path.to_path_buf(),
            line,
            what: format!("more than {} data rows", self.limits.max_rows),
            limit: "max_rows".into(),
            max: self.limits.max_rows,
        }
    }
}
