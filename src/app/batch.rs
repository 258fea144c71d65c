//! Fits of many logs, each on its own with the same request, in parallel ([`fit_each`]):
//! `greybox fit --each`, the Python `fit_many` and the Dask fleet; one summary [`Record`]
//! per log, a log that cannot be read or fitted a failed record, never an error.
//!
//! The logs are taken from a shared queue by plain threads (as many as the caller asks;
//! the command line and Python: rayon's pool, `RAYON_NUM_THREADS`, default the cores). The
//! fit of one log uses rayon (`rayon::join`, parallel iterators over holds and blocks),
//! whose tasks go to the global pool. The logs are deliberately not a rayon parallel
//! iterator: reading a log blocks on its decompression thread, and a rayon worker that
//! blocks while it holds stolen work (another log's read, nested in a join) serialises the
//! batch; measured on 20 logs with 2 cores, 108 % CPU and slower than one thread.

pub mod summary;

use super::plan::{Plan, fit_logs, plan};
use super::reading::{named, read_segments_from};
use super::request::FitRequest;
use crate::Error;
use crate::pmsm::{LogSource, PmsmFit};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;
use summary::Record;

/// File-name endings of the logs taken from a folder (lower case).
pub const LOG_ENDINGS: [&str; 8] =
    [".csv", ".csv.gz", ".parquet", ".pq", ".arrow", ".arrows", ".feather", ".ipc"];

/// The [`Plan`] of a batch's request: [`plan`]'s, `--method ls` refused.
///
/// # Errors
/// Those of [`plan`]; [`Error::InvalidOption`] naming `--method` for `--method ls`.
pub fn batch_plan(a: &FitRequest) -> crate::Result<Plan> {
    let plan = plan(a)?;
    if plan.pem.is_none() {
        return Err(Error::InvalidOption {
            option: "--method".into(),
            reason: "--each fits each log by the prediction-error method; --method ls is for one fit (drop --each)"
                .into(),
        });
    }
    Ok(plan)
}

/// Fits every log of `paths` on its own as `greybox fit --each` does, named `names`, on
/// `threads` plain threads (see the module doc), with the request `a` planned into `plan`;
/// a log's error is put in the caller's words by `words` (the command line's flags, the
/// Python keywords); `done` hears of each log's result as it finishes (in any order). A
/// log that cannot be read or fitted is a [`summary::Status::Failed`] record, never an
/// error; the records in the order of `paths`.
pub fn fit_each(
    a: &FitRequest,
    plan: &Plan,
    paths: &[PathBuf],
    names: &[String],
    threads: usize,
    words: impl Fn(Error) -> Error + Sync,
    done: impl Fn(&Path, &crate::Result<PmsmFit>) + Sync,
) -> Vec<Record> {
    let one = |k: usize| {
        let (path, name) = (&paths[k], &names[k]);
        let result = fit_one(a, plan, path, name).map_err(&words);
        done(path, &result);
        Record::new(path, name, result)
    };
    queue(paths.len(), threads, one)
}

/// Reads and fits one log as `greybox fit LOG` would (without its spinner), named `name`;
/// a panic inside becomes an error, so that the other logs are still fitted.
fn fit_one(a: &FitRequest, plan: &Plan, path: &Path, name: &str) -> crate::Result<PmsmFit> {
    let run = || {
        let t0 = Instant::now();
        // One experiment, or with --split-gaps one per segment (`name#1`, `name#2`, …).
        let logs =
            named(path, read_segments_from(LogSource::Path(path), &plan.csv, a.reading.split_gaps)?, name);
        let read_s = t0.elapsed().as_secs_f64();
        let (options, search, estimator) =
            plan.pem.as_ref().ok_or_else(|| Error::Solver("no fit planned".into()))?;
        let mut options = options.clone();
        options.pem.progress = false;
        fit_logs(a.pole_pairs, &options, *search, *estimator, &logs, t0, read_s)
    };
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(run)) {
        Ok(r) => r,
        Err(p) => {
            let what = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned());
            Err(Error::Solver(format!("internal error: {}", what.unwrap_or_else(|| "panic".into()))))
        }
    }
}

/// The logs of `pattern`: a folder's files ending in one of [`LOG_ENDINGS`], or the files a
/// glob matches; sorted by file name (then by path).
///
/// # Errors
/// [`Error::InvalidOption`] naming `--each` for a malformed glob, an unreadable folder or
/// entry, or no log at all.
pub fn expand(pattern: &str) -> crate::Result<Vec<PathBuf>> {
    let bad = |reason: String| Error::InvalidOption { option: "--each".into(), reason };
    let dir = Path::new(pattern);
    let mut paths: Vec<PathBuf> = if dir.is_dir() {
        let entries = std::fs::read_dir(dir).map_err(|e| bad(format!("folder {pattern}: {e}")))?;
        let mut v = Vec::new();
        for entry in entries {
            let p = entry.map_err(|e| bad(format!("folder {pattern}: {e}")))?.path();
            let name = p.file_name().map(|n| n.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
            if p.is_file() && LOG_ENDINGS.iter().any(|e| name.ends_with(e)) {
                v.push(p);
            }
        }
        if v.is_empty() {
            return Err(bad(format!("folder {pattern} holds no log ({})", LOG_ENDINGS.join(", "))));
        }
        v
    } else {
        let matches =
            glob::glob(pattern).map_err(|e| bad(format!("`{pattern}` is not a valid glob: {e}")))?;
        let mut v = Vec::new();
        for m in matches {
            let p = m.map_err(|e| bad(format!("{pattern}: {e}")))?;
            if p.is_file() {
                v.push(p);
            }
        }
        if v.is_empty() {
            return Err(bad(format!("`{pattern}` is neither a folder nor a glob matching any file")));
        }
        v
    };
    paths.sort_by(|x, y| x.file_name().cmp(&y.file_name()).then_with(|| x.cmp(y)));
    Ok(paths)
}

/// The name of a log as the reader gives it: the file name without `.gz` and a log
/// extension.
pub fn stem(p: &Path) -> String {
    let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    match name.rsplit_once('.') {
        Some((s, ext)) if LOG_ENDINGS.iter().any(|e| e[1..].eq_ignore_ascii_case(ext)) => s.to_string(),
        _ => name.to_string(),
    }
}

/// `work(0..n)` on `threads` plain threads taking the next index from a shared counter;
/// the results in index order.
fn queue<T: Send>(n: usize, threads: usize, work: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let mut done: Vec<(usize, T)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads.clamp(1, n.max(1)))
            .map(|_| {
                s.spawn(|| {
                    let mut out = Vec::new();
                    loop {
                        let k = next.fetch_add(1, Ordering::Relaxed);
                        if k >= n {
                            return out;
                        }
                        out.push((k, work(k)));
                    }
                })
            })
            .collect();
        // A worker's panic is caught per log in `fit_one`; one that escapes is re-raised.
        workers.into_iter().flat_map(|w| w.join().unwrap_or_else(|p| std::panic::resume_unwind(p))).collect()
    });
    done.sort_by_key(|(k, _)| *k);
    done.into_iter().map(|(_, t)| t).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stems() {
        assert_eq!(stem(Path::new("/a/run.csv.gz")), "run");
        assert_eq!(stem(Path::new("b/hot.PARQUET")), "hot");
        assert_eq!(stem(Path::new("notes.txt")), "notes.txt");
    }
}
