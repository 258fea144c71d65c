//! The general path of the CSV reader: from the first chunk holding a `"` to the end of
//! the file, records come from the `csv` parser (quoted fields, `""` escapes, line breaks
//! inside quotes), one at a time, with the line-length bound acting on the bytes first.

use std::io::Read;
use std::sync::mpsc::Receiver;

use super::line_limit::LineLimit;
use super::source::Item;
use super::table::State;
use super::{csv_error, float::parse_f64, quote};
use crate::error::{Error, Result};

/// The rest of a read, through the `csv` parser.
pub(super) struct Quoted<'s, 'a, 'r> {
    s: &'s mut State<'a>,
    first: Vec<u8>,
    rx: &'r Receiver<Item>,
    /// The header is still to be read.
    header: bool,
    /// `first` starts the file.
    at_start: bool,
}

impl<'s, 'a, 'r> Quoted<'s, 'a, 'r> {
    /// Continues the read in `s` with the chunk `first` and the chunks still to come.
    pub(super) fn new(
        s: &'s mut State<'a>,
        first: Vec<u8>,
        rx: &'r Receiver<Item>,
        header: bool,
        at_start: bool,
    ) -> Self {
        Self { s, first, rx, header, at_start }
    }

    /// Reads every remaining record into the state, stopping at the first error.
    pub(super) fn run(self) -> Result<()> {
        let Self { s, first, rx, mut header, at_start } = self;
        let path = s.path;
        let base = 1 + s.newlines;
        let limited =
            LineLimit::starting_at(Chunks { cur: first, pos: 0, rx }, s.limits.max_line_bytes, base);
        // Within the file, a leading empty line keeps the parser from dropping a byte order
        // mark (it does so only at the start of its input) and counts one line (below).
        let prefix: &[u8] = if at_start { b"" } else { b"\n" };
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(csv::Trim::All)
            .delimiter(s.delimiter.byte())
            .buffer_capacity(1 << 16)
            .from_reader(prefix.chain(limited));
        let mut record = csv::ByteRecord::new();
        let mut first_record = true;
        while rdr.read_byte_record(&mut record).map_err(|e| csv_error(path, e))? {
            let p = record.position().map_or(0, csv::Position::line);
            let line = match (at_start, first_record) {
                (true, _) => p,
                (false, true) => s.next_line,
                (false, false) => (p + base).saturating_sub(2),
            };
            first_record = false;
            if header {
                let names = record.iter().map(|f| String::from_utf8_lossy(f).into_owned()).collect();
                s.set_header(names, line)?;
                header = false;
                continue;
            }
            if record.len() != s.header.len() {
                let message = format!("row has {} fields, the header has {}", record.len(), s.header.len());
                return Err(Error::Csv { path: path.to_path_buf(), line, message });
            }
            if s.rows as u64 >= s.limits.max_rows {
                return Err(s.row_limit(line));
            }
            let row = s.rows;
            for (j, (column, idx)) in s.values.iter_mut().zip(&s.index).enumerate() {
                let Some(idx) = *idx else { continue };
                // The field count was checked against the header's, which holds idx.
                let field = record.get(idx).unwrap_or_default();
                let Some(x) = parse_f64(field) else {
                    let message = format!(
                        "column `{}` (data row {row}): cannot parse {} as a number",
                        s.header[idx],
                        quote(field)
                    );
                    return Err(Error::Csv { path: path.to_path_buf(), line, message });
                };
                if !x.is_finite() {
                    return Err(Error::NonFinite { column: s.header[idx].clone(), row, value: x });
                }
                if j == 0
                    && let Some(time) = s.time.as_mut()
                {
                    time.push(x)?;
                }
                column.push(x);
            }
            s.rows += 1;
        }
        if header {
            return s.set_header(Vec::new(), 1);
        }
        Ok(())
    }
}

/// The chunks of the stream as one reader.
struct Chunks<'r> {
    cur: Vec<u8>,
    pos: usize,
    rx: &'r Receiver<Item>,
}

impl Read for Chunks<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        while self.pos >= self.cur.len() {
            match self.rx.recv() {
                Ok(Ok(chunk)) => (self.cur, self.pos) = (chunk, 0),
                Ok(Err(e)) => return Err(e),
                Err(_) => return Ok(0),
            }
        }
        let n = buf.len().min(self.cur.len() - self.pos);
        buf[..n].copy_from_slice(&self.cur[self.pos..self.pos + n]);
        self.pos += n;
        Ok(n)
    }
}
