//! Report files: checked before the work, written atomically after it succeeds, never over
//! an input log.

use greybox::Error;
use std::path::{Path, PathBuf};

/// Checks before any work that the report `path` (`--json`) can be written: not one of
/// the `inputs`, in an existing directory. "-" (stdout) always can.
///
/// # Errors
/// [`Error::InvalidOption`] (option `json`) naming the path when it is an input or its
/// folder is missing.
pub fn check(path: &Path, inputs: &[PathBuf]) -> greybox::Result<()> {
    check_as("json", path, inputs)
}

/// [`check`] for the output given by the flag `flag` (its long name, e.g. `output`).
///
/// # Errors
/// [`Error::InvalidOption`] (option `flag`) naming the path when it is an input or its
/// folder is missing.
pub fn check_as(flag: &str, path: &Path, inputs: &[PathBuf]) -> greybox::Result<()> {
    if path.as_os_str() == "-" {
        return Ok(());
    }
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    };
    if let Some(input) = inputs.iter().find(|i| same(path, i)) {
        return Err(Error::InvalidOption {
            option: flag.into(),
            reason: format!("{} is an input log: refusing to overwrite it", input.display()),
        });
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(Error::InvalidOption {
            option: flag.into(),
            reason: format!("folder {} of {} does not exist", dir.display(), path.display()),
        });
    }
    Ok(())
}

/// Writes `text` to `path` ("-" = stdout) atomically: a temporary file in the same folder,
/// flushed, then renamed over the target, so that a reader or a concurrent run never sees
/// a partial file and a failure leaves any existing file intact.
///
/// # Errors
/// [`Error::Write`] with the path when the temporary file cannot be written or renamed.
pub fn write(path: &Path, text: &str) -> greybox::Result<()> {
    if path.as_os_str() == "-" {
        println!("{text}");
        return Ok(());
    }
    greybox::data::write::write_atomic(path, |f| {
        f.write_all(text.as_bytes())?;
        f.write_all(b"\n")
    })
}
