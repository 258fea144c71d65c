//! `greybox fit --each DIR_OR_GLOB`: every log of a folder (or every file a glob matches)
//! fitted on its own with the same flags, in parallel, into one summary (CSV and JSON), a
//! trend plot and a table.
//!
//! The logs are taken from a shared queue by as many plain threads as rayon's pool has
//! (`RAYON_NUM_THREADS`, default the cores). The fit of one log uses rayon (`rayon::join`,
//! parallel iterators over holds and blocks), whose tasks go to the global pool. The logs
//! are deliberately not a rayon parallel iterator: reading a log blocks on its
//! decompression thread, and a rayon worker that blocks while it holds stolen work (another
//! log's read, nested in a join) serialises the batch; measured on 20 logs with 2 cores,
//! 108 % CPU and slower than one thread.
//!
//! A log that cannot be read or fitted is reported on stderr (one line: its path and the
//! error) and kept in the summary as `failed`; the others are still fitted. Exit codes:
//! 0 every log fitted and trusted; 3 a log's fit is untrusted (and none failed) without
//! `--allow-unconverged`; 4 a log failed (the summary is written all the same); 1 an
//! error before any fit (no log matched, a flag the batch cannot honour, an output that
//! cannot be written).

pub mod summary;
mod trend;

use super::args::FitArgs;
use super::columns::named;
use super::output;
use super::plan::{Plan, fit_logs, plan};
use crate::Error;
use crate::data::Staged;
use crate::pmsm::PmsmFit;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;
use summary::{Record, Status};

/// Exit code when a log of the batch failed (could not be read or fitted).
pub const EXIT_FAILED: u8 = 4;
/// Exit code when a fit is untrusted (as `greybox fit`).
pub const EXIT_UNTRUSTED: u8 = 3;

/// File-name endings of the logs taken from a folder (lower case).
pub const LOG_ENDINGS: [&str; 8] =
    [".csv", ".csv.gz", ".parquet", ".pq", ".arrow", ".arrows", ".feather", ".ipc"];

/// Runs `greybox fit --each PATTERN`; returns the exit code (see the module doc).
///
/// # Errors
/// [`Error::InvalidOption`] naming `--each` when nothing matches or the glob is malformed,
/// naming `--method` for `--method ls`, naming `--summary`/`--trend` for an output that
/// cannot be written (checked before any fit); the errors of [`plan`]; [`Error::Write`]
/// when an output cannot be written after the fits.
pub fn run_batch(a: &FitArgs, pattern: &str) -> crate::Result<u8> {
    let t0 = Instant::now();
    let plan = batch_plan(a)?;
    let paths = expand(pattern)?;
    let summary_paths = a.summary.as_deref().map(summary_paths);
    let (csv, json) =
        (summary_paths.as_ref().map(|s| s.0.as_path()), summary_paths.as_ref().map(|s| s.1.as_path()));
    output::check_all(&[("--summary", csv), ("--summary", json), ("--trend", a.trend.as_deref())], &paths)?;
    let stems: Vec<String> = paths.iter().map(|p| stem(p)).collect();
    let names = super::logs::unique_names(&paths, &stems);
    let bar = progress(a.quiet, paths.len());
    let records = fit_each(a, &plan, &paths, &names, rayon::current_num_threads(), |path, result| {
        if let Err(e) = result {
            // The reader's errors name the file already.
            let shown = path.display().to_string();
            let e = e.to_string();
            let line = if e.contains(&shown) { e } else { format!("{shown}: {e}") };
            bar.suspend(|| eprintln!("error: {line}"));
        }
        bar.inc(1);
    });
    bar.finish_and_clear();
    let wall_s = t0.elapsed().as_secs_f64();
    let count = |s: Status| records.iter().filter(|r| r.status == s).count();
    let (ok, untrusted, failed) = (count(Status::Ok), count(Status::Untrusted), count(Status::Failed));
    if !a.quiet {
        super::output::stdout(&summary::table(&records))?;
    }
    let mut staged = Staged::new();
    if let Some((csv, json)) = &summary_paths {
        output::write(&mut staged, csv, summary::csv(&records)?.trim_end())?;
        output::write(&mut staged, json, &summary::json(pattern, &records, wall_s))?;
    }
    if let Some(p) = &a.trend {
        let svg = trend::svg(pattern, &records)?;
        staged.produce(p, |tmp| crate::report::plot::write_svg(tmp, &svg))?;
    }
    staged.commit()?;
    eprintln!("{} logs in {wall_s:.2} s: {ok} ok, {untrusted} untrusted, {failed} failed", records.len());
    Ok(if failed > 0 {
        eprintln!("exit code {EXIT_FAILED}: a log could not be read or fitted");
        EXIT_FAILED
    } else if untrusted > 0 && !a.allow_unconverged {
        eprintln!("exit code {EXIT_UNTRUSTED}: a fit is not to be trusted (--allow-unconverged: 0)");
        EXIT_UNTRUSTED
    } else {
        0
    })
}

/// The [`Plan`] of a batch's flags: [`plan`]'s, `--method ls` refused.
///
/// # Errors
/// Those of [`plan`]; [`Error::InvalidOption`] naming `--method` for `--method ls`.
pub fn batch_plan(a: &FitArgs) -> crate::Result<Plan> {
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
/// `threads` plain threads (see the module doc), with the flags `a` planned into `plan`;
/// `done` hears of each log's result as it finishes (in any order). A log that cannot be
/// read or fitted is a [`Status::Failed`] record, never an error; the records in the order
/// of `paths`.
pub fn fit_each(
    a: &FitArgs,
    plan: &Plan,
    paths: &[PathBuf],
    names: &[String],
    threads: usize,
    done: impl Fn(&Path, &crate::Result<PmsmFit>) + Sync,
) -> Vec<Record> {
    let one = |k: usize| {
        let (path, name) = (&paths[k], &names[k]);
        let result = fit_one(a, plan, path, name);
        done(path, &result);
        Record::new(path, name, result)
    };
    queue(paths.len(), threads, one)
}

/// Reads and fits one log as `greybox fit LOG` would (without its spinner), named `name`;
/// a panic inside becomes an error, so that the other logs are still fitted.
fn fit_one(a: &FitArgs, plan: &Plan, path: &Path, name: &str) -> crate::Result<PmsmFit> {
    let run = || {
        let t0 = Instant::now();
        // One experiment, or with --split-gaps one per segment (`name#1`, `name#2`, …).
        let logs = named(path, a.columns.read_segments(path, &plan.csv)?, name);
        let read_s = t0.elapsed().as_secs_f64();
        let (options, search, estimator) =
            plan.pem.as_ref().ok_or_else(|| Error::Solver("no fit planned".into()))?;
        let mut options = options.clone();
        options.pem.progress = false;
        fit_logs(a.pole_pairs, &options, *search, *estimator, &logs, t0, read_s)
    };
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(run)) {
        Ok(r) => r.map_err(super::errors::in_fit_words),
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

/// `PATH.csv` and `PATH.json` of `--summary PATH` (a `.csv` or `.json` given is dropped
/// first).
fn summary_paths(p: &Path) -> (PathBuf, PathBuf) {
    let base = match p.extension().and_then(|e| e.to_str()) {
        Some("csv" | "json") => p.with_extension(""),
        _ => p.to_path_buf(),
    };
    let with = |ext: &str| {
        let mut s = base.clone().into_os_string();
        s.push(ext);
        PathBuf::from(s)
    };
    (with(".csv"), with(".json"))
}

/// The progress bar over `n` logs on stderr; hidden with `-q` or when stderr is not a
/// terminal.
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

fn progress(quiet: bool, n: usize) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(n as u64);
    if let Ok(style) = ProgressStyle::with_template(
        "{spinner} fitting {pos}/{len} logs [{bar:30}] {elapsed_precise} (eta {eta})",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stems_and_summary_paths() {
        assert_eq!(stem(Path::new("/a/run.csv.gz")), "run");
        assert_eq!(stem(Path::new("b/hot.PARQUET")), "hot");
        assert_eq!(stem(Path::new("notes.txt")), "notes.txt");
        let (c, j) = summary_paths(Path::new("out/sum.json"));
        assert_eq!((c, j), (PathBuf::from("out/sum.csv"), PathBuf::from("out/sum.json")));
        let (c, _) = summary_paths(Path::new("out/sum.v2"));
        assert_eq!(c, PathBuf::from("out/sum.v2.csv"));
    }
}
