//! [`read_table`](super::read_table) itself: the header, then the data chunks parsed in
//! parallel batches (quote-free) or by the `csv` parser (from the first chunk with a `"`),
//! each merged in order so that the first bad row stops the read.

use std::path::Path;
use std::sync::mpsc::{Receiver, Sender};

use rayon::prelude::*;

use super::chunk::{ChunkError, Layout, Line, Parsed, parse};
use super::quoted::Quoted;
use super::source::{self, AHEAD, Item};
use super::{Delimiter, ReadLimits, Table, experiment_name, find_columns};
use crate::data::{TimeCheck, TimeSteps};
use crate::error::{Error, Result};

/// What the read knows at the end of the bytes merged so far.
pub(super) struct State<'a> {
    pub path: &'a Path,
    pub limits: &'a ReadLimits,
    pub wanted: &'a [(&'a str, bool)],
    pub delimiter: Delimiter,
    /// The header's names (empty until it is read).
    pub header: Vec<String>,
    /// Header position of each wanted column.
    pub index: Vec<Option<usize>>,
    /// Values per wanted column.
    pub values: Vec<Vec<f64>>,
    /// The streaming check of the time column; `None` for [`TimeCheck::Skip`].
    pub time: Option<TimeSteps>,
    /// Data rows accepted.
    pub rows: usize,
    /// `\n` merged.
    pub newlines: u64,
    /// Line of the next record: one plus the `\n` up to the break that ended the last one.
    pub next_line: u64,
    /// Bytes of data merged by the fast path, and what the file says it holds in all
    /// (uncompressed) and as stored: the columns grow to the rows these predict.
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
) -> Result<Table> {
    let io_err = |source| Error::Io { path: path.to_path_buf(), source };
    let mut s = State {
        path,
        limits,
        wanted,
        delimiter,
        header: Vec::new(),
        index: Vec::new(),
        values: vec![Vec::new(); wanted.len()],
        time: (time == TimeCheck::Streaming).then(|| TimeSteps::new(wanted.first().map_or("", |w| w.0))),
        rows: 0,
        newlines: 0,
        next_line: 1,
        merged_bytes: 0,
        size_hint: None,
        stored: None,
    };
    std::thread::scope(|scope| {
        let stream = source::spawn(scope, path, limits.max_line_bytes).map_err(io_err)?;
        (s.size_hint, s.stored) = (stream.size_hint, stream.stored);
        let (rx, recycle) = (&stream.rx, &stream.recycle);
        let mut header = true;
        let mut first = true;
        loop {
            let chunk = match rx.recv() {
                Ok(Ok(chunk)) => chunk,
                Ok(Err(e)) => return Err(io_err(e)),
                Err(_) if header => return s.set_header(Vec::new(), 1),
                Err(_) => break,
            };
            if memchr::memchr(b'"', &chunk).is_some() {
                Quoted::new(&mut s, chunk, rx, header, first).run()?;
                break;
            }
            if header {
                let Some(rest) = s.header_chunk(chunk, first)? else {
                    first = false;
                    continue;
                };
                header = false;
                first = false;
                if !s.batch(vec![rest], rx, recycle)? {
                    break;
                }
            } else if !s.batch(vec![chunk], rx, recycle)? {
                break;
            }
        }
        Ok(())
    })?;
    if s.header.iter().all(String::is_empty) || s.rows == 0 {
        return Err(Error::TooShort { name: experiment_name(path), len: 0, min: 1 });
    }
    let columns = s.values.into_iter().zip(&s.index).map(|(v, i)| i.map(|_| v)).collect();
    Ok(Table { name: experiment_name(path), header: s.header, columns })
}

impl State<'_> {
    /// The header from a quote-free chunk: `Ok(None)` when the chunk holds only line
    /// breaks, else the rest of the chunk after the header's line break.
    fn header_chunk(&mut self, chunk: Vec<u8>, first: bool) -> Result<Option<Vec<u8>>> {
        // A streaming reader checks line lengths before it parses (see `ChunkError::TooLong`).
        let layout = Layout::new(0, &[], self.limits.max_line_bytes, self.delimiter.byte());
        if let Some(ChunkError::TooLong { newlines }) = parse(&chunk, &layout, 0).error {
            return Err(self.too_long(self.newlines + newlines));
        }
        // The `csv` parser drops a UTF-8 byte order mark at the start of the file.
        let skip = if first && chunk.starts_with(b"\xef\xbb\xbf") { 3 } else { 0 };
        let mut pos = skip;
        while let Some(&b) = chunk.get(pos) {
            if !matches!(b, b'\n' | b'\r') {
                break;
            }
            self.newlines += u64::from(b == b'\n');
            pos += 1;
        }
        if pos == chunk.len() {
            return Ok(None);
        }
        let end = memchr::memchr2(b'\n', b'\r', &chunk[pos..]).map_or(chunk.len(), |p| pos + p);
        let d = self.delimiter.byte();
        let fields =
            chunk[pos..end].split(|&b| b == d).map(|f| String::from_utf8_lossy(f.trim_ascii()).into_owned());
        self.set_header(fields.collect(), 1 + self.newlines)?;
        let newline = chunk.get(end) == Some(&b'\n');
        self.newlines += u64::from(newline);
        self.next_line = 1 + self.newlines;
        Ok(Some(chunk.get(end + 1..).unwrap_or_default().to_vec()))
    }

    /// Checks the header ([`find_columns`]), found on 1-based line `line`, and keeps it.
    ///
    /// A header of one field that holds another delimiter (`t;ud;uq` read with `,`) fails
    /// with [`Error::Csv`] suggesting that delimiter, rather than as a missing column.
    pub(super) fn set_header(&mut self, header: Vec<String>, line: u64) -> Result<()> {
        let index = find_columns(self.path, &header, self.wanted, self.limits);
        if let (Err(Error::MissingColumn { .. }), [only]) = (&index, header.as_slice())
            && let Some(d) =
                Delimiter::ALL.into_iter().find(|d| *d != self.delimiter && only.contains(d.byte() as char))
        {
            let message = format!(
                "the header is one field, {}, which holds `{}`: read the file with the delimiter `{d}` \
                 (`--delimiter '{d}'`), not `{}`",
                super::quote(only.as_bytes()),
                if d == Delimiter::TAB { "\\t" } else { d.name() },
                self.delimiter,
            );
            return Err(Error::Csv { path: self.path.to_path_buf(), line, message });
        }
        self.index = index?;
        self.header = header;
        Ok(())
    }

    /// Parses `batch` and whatever more chunks are already waiting (up to [`AHEAD`], none
    /// with a `"`), in parallel, and merges them in order. `Ok(false)` at the end of the data.
    fn batch(
        &mut self,
        mut batch: Vec<Vec<u8>>,
        rx: &Receiver<Item>,
        recycle: &Sender<Vec<u8>>,
    ) -> Result<bool> {
        let mut tail = None;
        while batch.len() < AHEAD {
            match rx.try_recv() {
                Ok(Ok(c)) if memchr::memchr(b'"', &c).is_none() => batch.push(c),
                Ok(item) => {
                    tail = Some(item);
                    break;
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => break,
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    tail = Some(Ok(Vec::new()));
                    break;
                }
            }
        }
        let index = std::mem::take(&mut self.index);
        let layout =
            Layout::new(self.header.len(), &index, self.limits.max_line_bytes, self.delimiter.byte());
        let cap = self.cap();
        let parsed: Vec<Parsed> = if batch.len() == 1 {
            vec![parse(&batch[0], &layout, cap)]
        } else {
            batch.par_iter().map(|c| parse(c, &layout, cap)).collect()
        };
        let merged = batch.iter().zip(parsed).try_for_each(|(chunk, p)| self.merge(chunk, p, &layout));
        self.index = index;
        merged?;
        for chunk in batch {
            // The reading thread may have ended: then the buffer is simply dropped.
            recycle.send(chunk).ok();
        }
        match tail {
            None => Ok(true),
            Some(Err(e)) => Err(Error::Io { path: self.path.to_path_buf(), source: e }),
            Some(Ok(c)) if c.is_empty() => Ok(false),
            // A chunk with a quote: the `csv` parser takes over from there.
            Some(Ok(c)) => Quoted::new(self, c, rx, false, false).run().map(|()| false),
        }
    }

    /// Rows still allowed by `max_rows`.
    pub(super) fn cap(&self) -> usize {
        usize::try_from(self.limits.max_rows.saturating_sub(self.rows as u64)).unwrap_or(usize::MAX)
    }

    /// Appends a parsed chunk, after checking its time column row by row (unless
    /// [`TimeCheck::Skip`]); its error if any.
    fn merge(&mut self, chunk: &[u8], mut p: Parsed, layout: &Layout) -> Result<()> {
        let cap = self.cap();
        if p.rows >= cap && !matches!(p.error, Some(ChunkError::TooLong { .. })) {
            // Parsed with a looser cap than the rows merged since allow.
            p = parse(chunk, layout, cap);
        }
        if let Some(ChunkError::TooLong { newlines }) = p.error {
            return Err(self.too_long(self.newlines + newlines));
        }
        if let Some(time) = self.time.as_mut()
            && layout.index.first().is_some_and(Option::is_some)
        {
            p.columns[0].iter().try_for_each(|&t| time.push(t))?;
        }
        let base = 1 + self.newlines;
        let line = |l: Line| match l {
            Line::First => self.next_line,
            Line::After(n) => base + n,
        };
        let path = self.path.to_path_buf();
        match p.error {
            None => {}
            Some(ChunkError::TooLong { .. }) => unreachable!("returned above"),
            Some(ChunkError::Fields { line: l, len }) => {
                let expected = self.header.len();
                let message = format!("row has {len} fields, the header has {expected}");
                return Err(Error::Csv { path, line: line(l), message });
            }
            Some(ChunkError::RowLimit { line: l }) => return Err(self.row_limit(line(l))),
            Some(ChunkError::Number { line: l, row, idx, cell }) => {
                let message = format!(
                    "column `{}` (data row {}): cannot parse {cell} as a number",
                    self.header[idx],
                    self.rows + row
                );
                return Err(Error::Csv { path, line: line(l), message });
            }
            Some(ChunkError::NonFinite { row, idx, value }) => {
                return Err(Error::NonFinite {
                    column: self.header[idx].clone(),
                    row: self.rows + row,
                    value,
                });
            }
        }
        let need = self.rows + p.rows;
        if self.values.iter().zip(layout.index).any(|(v, i)| i.is_some() && v.capacity() < need) {
            self.reserve(chunk.len() as u64, need, layout.index);
        }
        for (v, c) in self.values.iter_mut().zip(&p.columns) {
            v.extend_from_slice(c);
        }
        self.rows += p.rows;
        self.merged_bytes += chunk.len() as u64;
        if let Some(n) = p.last_break {
            self.next_line = base + n;
        }
        self.newlines += p.newlines;
        Ok(())
    }

    /// Grows the wanted columns (header positions `index`), too short for `need` rows once this chunk of `bytes` is
    /// merged, to the rows the file holds as predicted from its size and the bytes per row
    /// so far (2 % more): the columns then grow about once instead of doubling (each
    /// doubling copies them and faults in fresh pages, a tenth of the read). Never less
    /// than a quarter more than `need`, so that growth stays geometric whatever the
    /// prediction. A prediction is a hint only: it never passes `max_rows`, and nothing is
    /// reserved (the columns double as they fill) when it is below `need`, or would take
    /// more than 32 times the stored file (a gzip file's recorded size is anyone's word).
    fn reserve(&mut self, bytes: u64, need: usize, index: &[Option<usize>]) {
        let (Some(size), Some(stored)) = (self.size_hint, self.stored) else { return };
        let seen = self.merged_bytes + bytes;
        if seen >= size || need == 0 {
            return;
        }
        let predicted = (need as f64 * size as f64 / seen as f64 * 1.02) as u64 + 64;
        let rows = predicted.max(need as u64 + need as u64 / 4).min(self.limits.max_rows);
        let present = index.iter().flatten().count() as u64;
        if rows <= need as u64 || rows.saturating_mul(8 * present) > stored.saturating_mul(32) {
            return;
        }
        let rows = usize::try_from(rows).unwrap_or(need);
        for (v, i) in self.values.iter_mut().zip(index) {
            if i.is_some() {
                v.reserve_exact(rows.saturating_sub(v.len()));
            }
        }
    }

    pub(super) fn too_long(&self, newlines: u64) -> Error {
        let max = self.limits.max_line_bytes;
        Error::LimitExceeded {
            path: self.path.to_path_buf(),
            line: 1 + newlines,
            what: format!("a line (record) longer than {max} bytes"),
            limit: "max_line_bytes".into(),
            max,
        }
    }

    pub(super) fn row_limit(&self, line: u64) -> Error {
        Error::LimitExceeded {
            path: self.path.to_path_buf(),
            line,
            what: format!("more than {} data rows", self.limits.max_rows),
            limit: "max_rows".into(),
            max: self.limits.max_rows,
        }
    }
}
