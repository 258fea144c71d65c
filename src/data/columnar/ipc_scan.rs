//! The rows each record batch of an Arrow IPC file or stream declares, from the message
//! headers alone: no body is read or decompressed. A 300 KB file can declare a batch of
//! 50 million rows (a compressed constant column); decoding that batch's columns would take
//! gigabytes before the first row could be checked, so the reader asks first.
//!
//! Layout (Arrow columnar format, "IPC File Format" and "Encapsulated message format"): a
//! file ends in its footer, a flatbuffer `Footer` whose `recordBatches` blocks give each
//! batch's offset and metadata length; a stream is a sequence of messages, each a
//! continuation marker `0xFFFFFFFF`, a 32-bit metadata length, the `Message` flatbuffer
//! (whose `bodyLength` says how far to skip) and the body; a zero length ends it.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use crate::error::{Error, Result};

/// Most messages a stream is scanned for (a file with more is not a log).
const MAX_MESSAGES: usize = 1 << 20;

fn bad(path: &Path, message: impl std::fmt::Display) -> Error {
    Error::Format { path: path.to_path_buf(), message: format!("Arrow IPC: {message}") }
}

/// The row count of the record batch whose encapsulated message (`0xFFFFFFFF`, length,
/// flatbuffer; or the legacy length, flatbuffer) is `meta`; `None` for other messages.
fn batch_rows(path: &Path, meta: &[u8]) -> Result<(Option<u64>, u64)> {
    let start = if meta.len() >= 8 && meta[..4] == [0xff; 4] { 8 } else { 4 };
    let body = meta.get(start..).ok_or_else(|| bad(path, "truncated message"))?;
    let message = arrow_ipc::root_as_message(body).map_err(|e| bad(path, e))?;
    let rows = message.header_as_record_batch().map(|b| u64::try_from(b.length()).unwrap_or(u64::MAX));
    Ok((rows, u64::try_from(message.bodyLength()).unwrap_or(u64::MAX)))
}

/// The rows the record batches of the IPC file or stream at `path` declare, summed.
///
/// # Errors
/// [`Error::Io`] when the file cannot be read; [`Error::Format`] when its headers are not
/// Arrow IPC.
pub(super) fn declared_rows(path: &Path) -> Result<u64> {
    let io = |source| Error::Io { path: path.to_path_buf(), source };
    let mut f = File::open(path).map_err(io)?;
    let len = f.metadata().map_err(io)?.len();
    let mut magic = [0u8; 6];
    f.read_exact(&mut magic).map_err(|_| bad(path, "too short"))?;
    if &magic == b"ARROW1" && len >= 16 {
        let mut tail = [0u8; 10];
        f.seek(SeekFrom::End(-10)).map_err(io)?;
        f.read_exact(&mut tail).map_err(io)?;
        let footer_len = arrow_ipc::reader::read_footer_length(tail).map_err(|e| bad(path, e))? as u64;
        let at = len.checked_sub(10 + footer_len).ok_or_else(|| bad(path, "footer longer than the file"))?;
        let mut footer = vec![0u8; footer_len as usize];
        f.seek(SeekFrom::Start(at)).map_err(io)?;
        f.read_exact(&mut footer).map_err(io)?;
        let footer = arrow_ipc::root_as_footer(&footer).map_err(|e| bad(path, e))?;
        let mut out = 0u64;
        for block in footer.recordBatches().into_iter().flatten() {
            let meta_len = u64::try_from(block.metaDataLength()).map_err(|_| bad(path, "negative length"))?;
            let offset = u64::try_from(block.offset()).map_err(|_| bad(path, "negative offset"))?;
            if offset.saturating_add(meta_len) > len {
                return Err(bad(path, "a batch lies beyond the end of the file"));
            }
            let mut meta = vec![0u8; meta_len as usize];
            f.seek(SeekFrom::Start(offset)).map_err(io)?;
            f.read_exact(&mut meta).map_err(io)?;
            out = out.saturating_add(batch_rows(path, &meta)?.0.unwrap_or(0));
        }
        return Ok(out);
    }
    // A stream: message after message.
    f.seek(SeekFrom::Start(0)).map_err(io)?;
    let mut out = 0u64;
    let mut at = 0u64;
    for _ in 0..MAX_MESSAGES {
        let mut word = [0u8; 4];
        if f.read_exact(&mut word).is_err() {
            return Ok(out);
        }
        let mut prefix = word.to_vec();
        if word == [0xff; 4] {
            f.read_exact(&mut word).map_err(|_| bad(path, "truncated message length"))?;
            prefix.extend(word);
        }
        let meta_len = u64::from(u32::from_le_bytes(word));
        if meta_len == 0 {
            return Ok(out);
        }
        if at + prefix.len() as u64 + meta_len > len {
            return Err(bad(path, "a message lies beyond the end of the file"));
        }
        let mut meta = prefix.clone();
        meta.resize(prefix.len() + meta_len as usize, 0);
        f.read_exact(&mut meta[prefix.len()..]).map_err(io)?;
        let (rows, body) = batch_rows(path, &meta)?;
        out = out.saturating_add(rows.unwrap_or(0));
        at = at.saturating_add(prefix.len() as u64 + meta_len).saturating_add(body);
        if at > len {
            return Err(bad(path, "a message body lies beyond the end of the file"));
        }
        f.seek(SeekFrom::Start(at)).map_err(io)?;
    }
    Err(bad(path, format!("more than {MAX_MESSAGES} messages")))
}
