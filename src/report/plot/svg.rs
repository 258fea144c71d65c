//! Writing a plot: the SVG file written atomically and the error of a plot that fails.

use crate::error::{Error, Result};
use std::path::Path;

/// Writes `svg` to `path` atomically (a temporary file in the same folder, renamed over
/// the target).
///
/// # Errors
/// [`Error::Write`] naming the path when it cannot be written (missing folder, no
/// permission); no partial or temporary file is left.
pub fn write_svg(path: &Path, svg: &str) -> Result<()> {
    crate::data::write_atomic(path, |w| w.write_all(svg.as_bytes()))
}

/// A drawing failure as the crate's error (option `plot`).
pub(crate) fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::InvalidOption { option: "plot".into(), reason: e.to_string() }
}
