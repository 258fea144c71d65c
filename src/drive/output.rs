//! Writing a simulated log: the CSV that `greybox fit` reads and the truth JSON beside it.

use super::sim::DriveLog;
use crate::data::Format;
use crate::data::Staged;
use crate::data::write_log;
use crate::error::Result;
use std::path::{Path, PathBuf};

impl DriveLog {
    /// The truth file of a log path: `log.csv` / `log.csv.gz` / `log.parquet` →
    /// `log.truth.json` (a name no scenario file `log.json` beside the log can take).
    pub fn truth_path(path: &Path) -> PathBuf {
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let stem = name.strip_suffix(".gz").unwrap_or(&name);
        let stem = match Format::of(Path::new(stem)) {
            Format::Csv => stem.strip_suffix(".csv").unwrap_or(stem),
            _ => Path::new(stem).file_stem().and_then(|s| s.to_str()).unwrap_or(stem),
        };
        path.with_file_name(format!("{stem}.truth.json"))
    }

    /// Writes the log to `path` (CSV with a time column `t`, gzip for `.gz`; Parquet or Arrow
    /// IPC by extension, [`write_log`]) and its truth to [`DriveLog::truth_path`], both or
    /// neither (staged, then renamed together).
    ///
    /// # Errors
    /// [`crate::Error::Write`] naming the file that could not be written.
    pub fn write(&self, path: &Path) -> Result<()> {
        let mut staged = Staged::new();
        self.stage(&mut staged, path)?;
        staged.commit()
    }

    /// Stages the log and its truth as [`DriveLog::write`] writes them, for the caller to
    /// commit with its other outputs.
    ///
    /// # Errors
    /// [`crate::Error::Write`] naming the file that could not be written.
    pub fn stage(&self, staged: &mut Staged, path: &Path) -> Result<()> {
        staged.produce(path, |tmp| write_log(tmp, &self.experiment, "t"))?;
        let json =
            serde_json::to_string_pretty(&self.truth).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
        staged.write(&Self::truth_path(path), |w| {
            w.write_all(json.as_bytes())?;
            w.write_all(b"\n")
        })
    }
}
