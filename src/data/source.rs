//! The bytes of a log, read (and gunzipped) on a second thread while the caller parses:
//! line-aligned chunks through a bounded channel, their buffers sent back for reuse.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::Path;
use std::sync::mpsc::{Receiver, Sender, SyncSender, TryRecvError, channel, sync_channel};
use std::thread::Scope;

/// Bytes read per chunk, before it is cut after its last line break.
pub(crate) const CHUNK_BYTES: usize = 1 << 18;

/// Chunks that may wait in the channel: with [`CHUNK_BYTES`], 4 MiB read ahead.
pub(crate) const AHEAD: usize = 16;

/// One item of the stream: a chunk, or the error that ended it.
pub(crate) type Item = std::io::Result<Vec<u8>>;

/// The receiving end of a stream: the chunks, the way back for their buffers, and the
/// size of the data when the file tells it.
pub(crate) struct Stream {
    /// The chunks, in order.
    pub rx: Receiver<Item>,
    /// Buffers of merged chunks, for the reading thread to fill again: a fresh buffer
    /// costs its page faults, which were a third of the reading thread's time.
    pub recycle: Sender<Vec<u8>>,
    /// Bytes of data: a plain file's length, or the size a gzip file's last 4 bytes
    /// record (its last member's, modulo 2³²). A hint for reserving the columns only.
    pub size_hint: Option<u64>,
    /// Bytes of the file as stored (compressed for gzip); `None` for standard input.
    pub stored: Option<u64>,
}

/// Opens `path` on the calling thread (so that a missing file is reported at once) and
/// starts a thread in `scope` that streams its bytes, gunzipped when they start with the
/// gzip magic `1f 8b`, as chunks that end just after a line break (`\n` or `\r`).
///
/// A chunk is cut after the last line break in [`CHUNK_BYTES`] newly read bytes; a chunk
/// without one grows until a line break arrives, or until it is longer than `max_line`
/// bytes, when it is sent as it is and the stream ends (the reader then reports the long
/// line: no line break in more than `max_line` bytes is too long, quoted or not). The last
/// chunk ends where the data ends. The thread stops when the receiver is dropped, so memory
/// stays within [`AHEAD`] chunks plus one line, and as many buffers sent back.
///
/// # Errors
/// Opening or reading the first bytes, or starting the thread; later read or decompression errors arrive as the
/// stream's last item.
pub(crate) fn spawn<'scope>(
    scope: &'scope Scope<'scope, '_>,
    path: &Path,
    max_line: u64,
) -> std::io::Result<Stream> {
    // `-` is standard input (a pipe: `zcat log.csv.gz | greybox fit - …`).
    let (input, stored, tail): (Box<dyn Read + Send>, _, _) = if path == Path::new("-") {
        (Box::new(std::io::stdin()), None, None)
    } else {
        let mut file = File::open(path)?;
        let stored = file.metadata().ok().filter(std::fs::Metadata::is_file).map(|m| m.len());
        let tail = if stored.is_some_and(|n| n >= 18) { last_u32(&mut file)? } else { None };
        (Box::new(file), stored, tail)
    };
    let mut buf = BufReader::with_capacity(1 << 16, input);
    let gz = buf.fill_buf()?.starts_with(&[0x1f, 0x8b]);
    let size_hint = if gz { tail.map(u64::from) } else { stored };
    let reader: Box<dyn Read + Send> =
        if gz { Box::new(flate2::read::MultiGzDecoder::new(buf)) } else { Box::new(buf) };
    let (tx, rx) = sync_channel(AHEAD);
    let (recycle, back) = channel();
    // A thread that cannot be started is an I/O error, not a panic.
    std::thread::Builder::new()
        .name("greybox-read".into())
        .spawn_scoped(scope, move || produce(reader, &tx, &back, max_line))?;
    Ok(Stream { rx, recycle, size_hint, stored })
}

/// The file's last 4 bytes as a little-endian number (a gzip member's ISIZE), the file
/// then rewound.
fn last_u32(file: &mut File) -> std::io::Result<Option<u32>> {
    let mut b = [0; 4];
    let tail = file.seek(SeekFrom::End(-4)).and_then(|_| file.read_exact(&mut b));
    file.rewind()?;
    Ok(tail.ok().map(|()| u32::from_le_bytes(b)))
}

fn produce(mut reader: Box<dyn Read + Send>, tx: &SyncSender<Item>, back: &Receiver<Vec<u8>>, max_line: u64) {
    let mut buf: Vec<u8> = Vec::with_capacity(CHUNK_BYTES);
    // Bytes at the start of `buf` known to hold no line break.
    let mut scanned = 0;
    loop {
        let eof = match fill(&mut reader, &mut buf) {
            Ok(eof) => eof,
            Err(e) => {
                // What was read before the error is parsed first, as a stream reader would.
                if !buf.is_empty() {
                    let _ = tx.send(Ok(std::mem::take(&mut buf)));
                }
                let _ = tx.send(Err(e));
                return;
            }
        };
        let long = buf.len() as u64 > max_line;
        let (cut, last) = match memchr::memrchr2(b'\n', b'\r', &buf[scanned..]) {
            _ if eof => (buf.len(), true),
            Some(p) => (scanned + p + 1, false),
            None if long => (buf.len(), true),
            None => {
                scanned = buf.len();
                continue;
            }
        };
        let tail = buf.len() - cut;
        let mut next = match back.try_recv() {
            Ok(mut b) => {
                b.clear();
                // Room for the tail and a chunk, so that `fill` never moves the buffer.
                b.reserve(tail + CHUNK_BYTES);
                b
            }
            Err(TryRecvError::Empty | TryRecvError::Disconnected) => Vec::with_capacity(tail + CHUNK_BYTES),
        };
        next.extend_from_slice(&buf[cut..]);
        buf.truncate(cut);
        scanned = next.len();
        if !buf.is_empty() && tx.send(Ok(std::mem::replace(&mut buf, next))).is_err() {
            return;
        }
        if last {
            return;
        }
    }
}

/// Appends up to [`CHUNK_BYTES`] bytes to `buf`; `true` at the end of the data. On an
/// error the bytes read before it stay in `buf`.
fn fill(reader: &mut dyn Read, buf: &mut Vec<u8>) -> std::io::Result<bool> {
    let start = buf.len();
    // Zeroing a reused buffer touches memory already mapped (cheap); reading then writes
    // over it.
    buf.resize(start + CHUNK_BYTES, 0);
    let mut filled = start;
    let end = buf.len();
    let result = loop {
        match reader.read(&mut buf[filled..end]) {
            Ok(0) => break Ok(true),
            Ok(n) => {
                filled += n;
                if filled == end {
                    break Ok(false);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => break Err(e),
        }
    };
    buf.truncate(filled);
    result
}

/// The line bound of a stream of chunks, as a streaming reader bounds lines before it parses
/// them: the bytes since the last line break outside quotes (a `"` toggles quoting, stray or
/// not), checked at each such break and at each chunk's end.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Bound {
    run: u64,
    quoted: bool,
}

impl Bound {
    /// The `\n` of `chunk`; `Err` with the `\n` before the point where a line passes `max`.
    pub(crate) fn scan(&mut self, chunk: &[u8], max: u64) -> std::result::Result<u64, u64> {
        let (mut newlines, mut start) = (0, 0);
        for i in memchr::memchr3_iter(b'"', b'\n', b'\r', chunk) {
            if chunk[i] == b'"' {
                self.quoted = !self.quoted;
                continue;
            }
            if !self.quoted {
                self.run += (i - start) as u64;
                if self.run > max {
                    return Err(newlines);
                }
                (self.run, start) = (0, i + 1);
            }
            newlines += u64::from(chunk[i] == b'\n');
        }
        self.run += (chunk.len() - start) as u64;
        if self.run > max { Err(newlines) } else { Ok(newlines) }
    }
}
