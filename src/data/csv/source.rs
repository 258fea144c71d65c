//! The bytes of a log, read (and gunzipped) on a second thread while the caller parses:
//! line-aligned chunks through a bounded channel.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::Scope;

/// Bytes read per chunk, before it is cut after its last line break.
pub(super) const CHUNK_BYTES: usize = 1 << 18;

/// Chunks that may wait in the channel: with [`CHUNK_BYTES`], 4 MiB read ahead.
pub(super) const AHEAD: usize = 16;

/// One item of the stream: a chunk, or the error that ended it.
pub(super) type Item = std::io::Result<Vec<u8>>;

/// Opens `path` on the calling thread (so that a missing file is reported at once) and
/// starts a thread in `scope` that streams its bytes, gunzipped when they start with the
/// gzip magic `1f 8b`, as chunks that end just after a line break (`\n` or `\r`).
///
/// A chunk is cut after the last line break in [`CHUNK_BYTES`] newly read bytes; a chunk
/// without one grows until a line break arrives, or until it is longer than `max_line`
/// bytes, when it is sent as it is and the stream ends (the reader then reports the long
/// line: no line break in more than `max_line` bytes is too long, quoted or not). The last
/// chunk ends where the data ends. The thread stops when the receiver is dropped, so memory
/// stays within [`AHEAD`] chunks plus one line.
///
/// # Errors
/// Opening or reading the first bytes, or starting the thread; later read or decompression errors arrive as the
/// stream's last item.
pub(super) fn spawn<'scope>(
    scope: &'scope Scope<'scope, '_>,
    path: &Path,
    max_line: u64,
) -> std::io::Result<Receiver<Item>> {
    // `-` is standard input (a pipe: `zcat log.csv.gz | greybox fit - …`).
    let input: Box<dyn Read + Send> =
        if path == Path::new("-") { Box::new(std::io::stdin()) } else { Box::new(File::open(path)?) };
    let mut buf = BufReader::with_capacity(1 << 16, input);
    let gz = buf.fill_buf()?.starts_with(&[0x1f, 0x8b]);
    let reader: Box<dyn Read + Send> =
        if gz { Box::new(flate2::read::MultiGzDecoder::new(buf)) } else { Box::new(buf) };
    let (tx, rx) = sync_channel(AHEAD);
    // A thread that cannot be started is an I/O error, not a panic.
    std::thread::Builder::new()
        .name("greybox-read".into())
        .spawn_scoped(scope, move || produce(reader, &tx, max_line))?;
    Ok(rx)
}

fn produce(mut reader: Box<dyn Read + Send>, tx: &SyncSender<Item>, max_line: u64) {
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
        let mut next = Vec::with_capacity(CHUNK_BYTES + (buf.len() - cut));
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
    // `read_to_end` fills the spare capacity without zeroing it first.
    let n = reader.take(CHUNK_BYTES as u64).read_to_end(buf)?;
    Ok(n < CHUNK_BYTES)
}
