//! Outputs that appear together or not at all: every file of a command is written to a
//! temporary beside its target, flushed and synced, and the temporaries are renamed over
//! the targets only after all of them have been written ([`Staged::commit`]); dropped
//! without a commit (an error, a panic), they are removed and every old file is intact.
//!
//! Temporaries are named `.greybox-tmp.PID.SEQ.NAME` (the target's own name last, so its
//! extension still says its format). Every live one is registered, so that a signal
//! handler can remove them ([`remove_temporaries`], which `greybox` calls on SIGINT and
//! SIGTERM); a process killed outright (SIGKILL) cannot clean up, so each new write first
//! removes the temporaries of its folder whose process no longer runs (Linux: no
//! `/proc/PID`).

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Prefix of every temporary file name.
pub const TEMPORARY_PREFIX: &str = ".greybox-tmp.";

/// The temporaries written and not yet renamed or removed, of every thread.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Sequence number of the temporaries of this process.
static SEQ: AtomicUsize = AtomicUsize::new(0);

fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Removes every temporary this process has not renamed yet (for a signal handler: the
/// files of an interrupted command go, the old outputs stay).
pub fn remove_temporaries() {
    for tmp in live().drain(..) {
        let _ = std::fs::remove_file(tmp);
    }
}

/// Removes the temporaries in `dir` left by processes that no longer run (Linux; a no-op
/// where `/proc` is not there to tell).
fn sweep_stale(dir: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(TEMPORARY_PREFIX)) else { continue };
        let Some(pid) = rest.split('.').next().and_then(|p| p.parse::<u32>().ok()) else { continue };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Files written together: see the module documentation.
#[derive(Debug, Default)]
pub struct Staged {
    /// `(temporary, target)` of every file written so far.
    files: Vec<(PathBuf, PathBuf)>,
}

impl Staged {
    /// An empty set of outputs.
    pub fn new() -> Self {
        Self::default()
    }

    /// A fresh temporary path beside `path`, ending in its file name, registered as live.
    fn temporary(path: &Path) -> PathBuf {
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        sweep_stale(dir);
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let seq = SEQ.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!("{TEMPORARY_PREFIX}{}.{seq}.{name}", std::process::id()));
        live().push(tmp.clone());
        tmp
    }

    /// Writes what `fill` writes as the future `path` (buffered, flushed and synced).
    ///
    /// # Errors
    /// [`Error::Write`] naming `path` when the temporary cannot be created or written
    /// (it is then removed).
    pub fn write(
        &mut self,
        path: &Path,
        fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<()> {
        self.produce(path, |tmp| {
            let result = (|| {
                let file = std::fs::File::create(tmp)?;
                let mut w = std::io::BufWriter::new(file);
                fill(&mut w)?;
                let file = w.into_inner().map_err(|e| e.into_error())?;
                file.sync_all()
            })();
            result.map_err(|source| Error::Write { path: path.to_path_buf(), source })
        })
    }

    /// Lets `make` write the future `path` at the temporary path it is given (a writer of
    /// the library that takes a path and picks the format from its extension).
    ///
    /// # Errors
    /// Those of `make` (the temporary is then removed).
    pub fn produce(&mut self, path: &Path, make: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
        let tmp = Self::temporary(path);
        match make(&tmp) {
            Ok(()) => {
                self.files.push((tmp, path.to_path_buf()));
                Ok(())
            }
            Err(e) => {
                forget(&tmp);
                let _ = std::fs::remove_file(&tmp);
                Err(e)
            }
        }
    }

    /// Renames every temporary over its target, in the order written.
    ///
    /// # Errors
    /// [`Error::Write`] naming the target whose rename failed (the temporaries not yet
    /// renamed are removed).
    pub fn commit(mut self) -> Result<()> {
        let files = std::mem::take(&mut self.files);
        for (i, (tmp, target)) in files.iter().enumerate() {
            let renamed = std::fs::rename(tmp, target);
            forget(tmp);
            if let Err(source) = renamed {
                for (tmp, _) in &files[i..] {
                    forget(tmp);
                    let _ = std::fs::remove_file(tmp);
                }
                return Err(Error::Write { path: target.clone(), source });
            }
        }
        Ok(())
    }
}

/// Unregisters a temporary (renamed or removed).
fn forget(tmp: &Path) {
    live().retain(|p| p != tmp);
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (tmp, _) in self.files.drain(..) {
            forget(&tmp);
            let _ = std::fs::remove_file(&tmp);
        }
    }
}
