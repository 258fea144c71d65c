//! Outputs that appear together or not at all: every file of a command is written to a
//! temporary beside its target, flushed and synced, and the temporaries are renamed over
//! the targets only after all of them have been written ([`Staged::commit`]); dropped
//! without a commit (an error, a panic), they are removed and every old file is intact.
//!
//! Temporaries are named `.greybox-tmp.PID.SEQ.NAME` (the target's own name last, so its
//! extension still says its format). Every live one is registered, so that a signal
//! handler can remove them ([`interrupt_removing_temporaries`], which `greybox` calls on SIGINT
//! and SIGTERM, ending the process itself); a process killed outright (SIGKILL) cannot clean up, so each new write first
//! removes the temporaries of its folder whose process no longer runs (Linux: no
//! `/proc/PID`). A set of several files is renamed under a manifest (`.commit`, the pairs
//! to rename): a process killed among its renames leaves it, and the next write in that
//! folder finishes the renames, so the set ends all new, never part new and part old.

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

/// For a signal handler: removes every temporary the process has not renamed yet, then
/// calls `end` with how many it removed, still holding the registry; `end` is the caller's
/// way to end the process (it cannot return: [`std::convert::Infallible`]) (the command line's: a message on stderr and its exit code), so
/// the files of an interrupted command go and the old outputs stay. A [`Staged::commit`]
/// under way holds the registry until all its files are renamed, so this waits for it (the
/// outputs are then all new, never some new beside some old); and, as `end` does not
/// return, no other thread creates a temporary after the removal (each is created and
/// registered under the registry's lock).
pub fn interrupt_removing_temporaries(end: impl FnOnce(usize) -> std::convert::Infallible) -> ! {
    INTERRUPTED.store(true, Ordering::SeqCst);
    let mut live = live();
    let n = live.len();
    for tmp in live.drain(..) {
        let _ = std::fs::remove_file(tmp);
    }
    match end(n) {}
}

/// Set when [`interrupt_removing_temporaries`] has begun: the process is ending with its code.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether a signal handler has begun [`interrupt_removing_temporaries`]: the main thread then
/// waits for it to end the process rather than racing it with another exit code.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Ending of a commit's manifest: the `(temporary, target)` pairs of a set being renamed.
const MANIFEST: &str = ".commit";

/// The temporaries in `dir` of processes that no longer run (Linux; none where `/proc` is
/// not there to tell), paired with whether each is a commit manifest.
fn stale(dir: &Path) -> Vec<(PathBuf, bool)> {
    if !Path::new("/proc/self").exists() {
        return Vec::new();
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    entries
        .flatten()
        .filter_map(|entry| {
            let name = entry.file_name().to_str()?.to_string();
            let pid = name.strip_prefix(TEMPORARY_PREFIX)?.split('.').next()?.parse::<u32>().ok()?;
            let dead = pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists();
            dead.then(|| (entry.path(), name.ends_with(MANIFEST)))
        })
        .collect()
}

/// Finishes the sets of dead processes whose manifest is in `dir` (a kill during a commit's
/// renames: the set is rolled forward, every file new), then removes their other
/// temporaries (a kill before the commit: every file stays old).
fn sweep_stale(dir: &Path) {
    let found = stale(dir);
    for (manifest, _) in found.iter().filter(|(_, m)| *m) {
        if let Ok(text) = std::fs::read_to_string(manifest) {
            for (tmp, target) in text.lines().filter_map(|l| l.split_once('\t')) {
                if Path::new(tmp).exists() && !special(Path::new(target)) {
                    let _ = std::fs::rename(tmp, target);
                }
            }
        }
        let _ = std::fs::remove_file(manifest);
    }
    for (tmp, _) in found.iter().filter(|(_, m)| !*m) {
        let _ = std::fs::remove_file(tmp);
    }
}

/// Writes the manifest of `files` (absolute `temporary<TAB>target` lines) into every folder
/// of the set, each complete or not at all (written as a temporary, synced, renamed), so
/// that a later [`sweep_stale`] in any of them can finish a commit killed among its renames.
/// Returns the manifests written (the commit goes on without those that could not be).
fn write_manifest(files: &[(PathBuf, PathBuf)]) -> Vec<PathBuf> {
    use std::io::Write as _;
    let absolute = |p: &Path| std::path::absolute(p).ok().and_then(|p| p.to_str().map(String::from));
    let mut text = String::new();
    for (tmp, target) in files {
        let (Some(tmp), Some(target)) = (absolute(tmp), absolute(target)) else { return Vec::new() };
        text.push_str(&format!("{tmp}\t{target}\n"));
    }
    let mut dirs: Vec<&Path> = Vec::new();
    for (_, target) in files {
        let dir = target.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !dirs.contains(&dir) {
            dirs.push(dir);
        }
    }
    let seq = SEQ.fetch_add(1, Ordering::Relaxed);
    let name = format!("{TEMPORARY_PREFIX}{}.{seq}", std::process::id());
    let mut written = Vec::new();
    for dir in dirs {
        let (part, manifest) = (dir.join(format!("{name}.part")), dir.join(format!("{name}{MANIFEST}")));
        let result = (|| {
            let mut f = std::fs::File::create(&part)?;
            f.write_all(text.as_bytes())?;
            f.sync_all()?;
            std::fs::rename(&part, &manifest)
        })();
        match result {
            Ok(()) => written.push(manifest),
            Err(_) => {
                let _ = std::fs::remove_file(&part);
            }
        }
    }
    written
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
        // A device or pipe (`/dev/null`, `/dev/stdout`) is written into from the system's
        // temporary folder: its own folder may not be writable, and it is never replaced.
        let system;
        let dir = match path.parent().filter(|d| !d.as_os_str().is_empty()) {
            _ if special(path) => {
                system = std::env::temp_dir();
                system.as_path()
            }
            Some(d) => d,
            None => Path::new("."),
        };
        sweep_stale(dir);
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let seq = SEQ.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!("{TEMPORARY_PREFIX}{}.{seq}.{name}", std::process::id()));
        // Created (empty) and registered under one lock: a signal handler sees it or none.
        let mut live = live();
        let _ = std::fs::File::create(&tmp);
        live.push(tmp.clone());
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
        // The registry is held across all renames: a signal handler's
        // [`interrupt_removing_temporaries`] waits until the set is complete.
        let mut live = live();
        let mut forget = |tmp: &PathBuf| live.retain(|p| p != tmp);
        // More than one file: a manifest, so that a kill among the renames is rolled forward.
        let manifests = if files.len() > 1 { write_manifest(&files) } else { Vec::new() };
        let _done = Removal(manifests);
        for (i, (tmp, target)) in files.iter().enumerate() {
            let renamed = if special(target) { copy_into(tmp, target) } else { std::fs::rename(tmp, target) };
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

/// Whether `target` exists and is neither a regular file nor a folder: a device such as
/// `/dev/null`, a pipe, a terminal. Renaming a file over it would replace the device with
/// a file (`--json /dev/null` run as root once made `/dev/null` a regular file, which every
/// later reader of `/dev/null` then read back), so it is written into instead.
fn special(target: &Path) -> bool {
    std::fs::metadata(target).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Copies the temporary `tmp` into the existing special file `target`, then removes it.
fn copy_into(tmp: &Path, target: &Path) -> std::io::Result<()> {
    let mut from = std::fs::File::open(tmp)?;
    let mut to = std::fs::OpenOptions::new().write(true).open(target)?;
    std::io::copy(&mut from, &mut to)?;
    std::fs::remove_file(tmp)
}

/// Removes the manifests when a commit ends, renamed or failed.
struct Removal(Vec<PathBuf>);

impl Drop for Removal {
    fn drop(&mut self) {
        for m in &self.0 {
            let _ = std::fs::remove_file(m);
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A dead process (a PID above Linux's largest) killed among its renames: the next
    /// write in the folder finishes its set; one killed before its commit: its temporary
    /// goes and the old file stays.
    #[test]
    fn a_commit_killed_among_its_renames_is_rolled_forward() {
        if !Path::new("/proc/self").exists() {
            eprintln!("skipped: no /proc to tell dead processes");
            return;
        }
        let dir = std::env::temp_dir().join(format!("greybox-staged-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let dead = format!("{TEMPORARY_PREFIX}999999999");
        let (a, b, c) = (dir.join("a.json"), dir.join("b.csv"), dir.join("c.svg"));
        for p in [&a, &b, &c] {
            std::fs::write(p, "old").unwrap();
        }
        // Set 1 (a, b): a renamed already, b's temporary still there, the manifest left.
        let tmp_b = dir.join(format!("{dead}.1.b.csv"));
        std::fs::write(&a, "new").unwrap();
        std::fs::write(&tmp_b, "new").unwrap();
        let lines = format!(
            "{}\t{}\n{}\t{}\n",
            dir.join(format!("{dead}.0.a.json")).display(),
            a.display(),
            tmp_b.display(),
            b.display()
        );
        std::fs::write(dir.join(format!("{dead}.2{MANIFEST}")), lines).unwrap();
        // Set 2 (c): killed before its commit.
        std::fs::write(dir.join(format!("{dead}.3.c.svg")), "new").unwrap();
        let mut staged = Staged::new();
        staged.write(&dir.join("d.txt"), |w| w.write_all(b"d")).unwrap();
        staged.commit().unwrap();
        let read = |p: &Path| std::fs::read_to_string(p).unwrap();
        assert_eq!((read(&a), read(&b), read(&c)), ("new".into(), "new".into(), "old".into()));
        let left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(TEMPORARY_PREFIX))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A device stays a device: written into, not replaced by a renamed file (before, a
    /// root process's `--json /dev/null` left `/dev/null` a regular file); the temporary
    /// gone from the system's temporary folder.
    #[cfg(unix)]
    #[test]
    fn a_device_is_written_into_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let null = Path::new("/dev/null");
        if !std::fs::metadata(null).is_ok_and(|m| m.file_type().is_char_device()) {
            eprintln!("skipped: /dev/null is no character device here");
            return;
        }
        let mut staged = Staged::new();
        staged.write(null, |w| w.write_all(b"report")).unwrap();
        staged.write(null, |w| w.write_all(b"again")).unwrap();
        staged.commit().unwrap();
        assert!(std::fs::metadata(null).unwrap().file_type().is_char_device());
        let left: Vec<String> = std::fs::read_dir(std::env::temp_dir())
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| {
                n.starts_with(&format!("{TEMPORARY_PREFIX}{}.", std::process::id())) && n.ends_with(".null")
            })
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }
}
