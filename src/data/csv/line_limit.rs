//! The line-length bound of the CSV reader: it acts on the bytes before the `csv` parser,
//! which would otherwise buffer a whole record of any length.

use std::io::Read;

/// The line where a [`LineLimit`] stopped, carried through the `csv` parser as the
/// payload of an [`std::io::Error`].
#[derive(Debug)]
pub(super) struct LineTooLong {
    pub(super) line: u64,
    pub(super) max: u64,
}

impl std::fmt::Display for LineTooLong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "line {} is longer than {} bytes", self.line, self.max)
    }
}

impl std::error::Error for LineTooLong {}

/// A reader that fails once more than `max` bytes follow the last line break outside
/// quotes: the `csv` parser buffers a whole record, so the bound must act before it.
///
/// `\r` and `\n` both end a line (CR, LF and CRLF files), except inside a quoted field,
/// where they belong to the record (a `"` toggles quoting, so `""` inside a quoted field
/// keeps it open; a stray `"` inside an unquoted field, which `csv` takes literally, makes
/// the following lines count as one until the next `"`). The line number in the error
/// counts every `\n`, as `csv` does.
pub(super) struct LineLimit<R> {
    inner: R,
    max: u64,
    /// Bytes of the current record since its last line break outside quotes.
    run: u64,
    /// 1-based number of the line being read.
    line: u64,
    /// Inside a quoted field.
    quoted: bool,
}

impl<R: Read> LineLimit<R> {
    /// A limit on `inner`, whose first byte starts 1-based line `line`, outside quotes.
    pub(super) fn starting_at(inner: R, max: u64, line: u64) -> Self {
        Self { inner, max, run: 0, line, quoted: false }
    }
}

impl<R: Read> Read for LineLimit<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        let mut start = 0;
        for (i, &b) in buf[..n].iter().enumerate() {
            if b == b'"' {
                self.quoted = !self.quoted;
            } else if matches!(b, b'\n' | b'\r') && !self.quoted {
                self.check(i - start)?;
                self.run = 0;
                start = i + 1;
            }
            self.line += u64::from(b == b'\n');
        }
        self.check(n - start)?;
        Ok(n)
    }
}

impl<R> LineLimit<R> {
    /// Adds `bytes` to the current record, failing once it is longer than the limit.
    fn check(&mut self, bytes: usize) -> std::io::Result<()> {
        self.run += bytes as u64;
        if self.run > self.max {
            return Err(std::io::Error::other(LineTooLong { line: self.line, max: self.max }));
        }
        Ok(())
    }
}
