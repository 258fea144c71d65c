//! The decoding budget of a columnar log, checked from its metadata before anything is
//! decoded: a few hundred kilobytes of compressed constants can declare gigabytes of
//! values (a decompression bomb), which a real drive log of that length never does.

use std::path::Path;

use crate::error::{Error, Result};

/// Bytes the wanted columns may take decoded whatever the file's size.
const DECODE_BUDGET: u64 = 128 << 20;
/// Decoded size over file size beyond which (and beyond [`DECODE_BUDGET`]) a file is a
/// decompression bomb, not a log: a drive log's noisy floats compress a few times at most.
const BOMB_RATIO: u64 = 50;

/// Refuses, before anything is decoded, a file whose wanted columns would take `decoded`
/// bytes (for `rows` declared rows) beyond [`DECODE_BUDGET`] and [`BOMB_RATIO`] times the
/// file's `size` \[bytes\].
///
/// # Errors
/// [`Error::Format`] naming the file, the rows and the sizes.
pub(super) fn check_budget(path: &Path, size: u64, rows: u64, decoded: u64) -> Result<()> {
    if decoded <= DECODE_BUDGET || decoded <= BOMB_RATIO.saturating_mul(size) {
        return Ok(());
    }
    Err(Error::Format {
        path: path.to_path_buf(),
        message: format!(
            "declares {rows} rows ({} MB decoded) in a file of {} kB, more than {BOMB_RATIO} times its size: not \
             read (a decompression bomb?). A real log of that length is larger: write it without such compression",
            decoded >> 20,
            size >> 10
        ),
    })
}
