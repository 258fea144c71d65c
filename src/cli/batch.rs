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

mod trend;

use super::args::FitArgs;
use super::output;
use crate::app::summary::{self, Status};
use crate::app::{FitRequest, batch_plan, expand, fit_each, stem};
use crate::data::Staged;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Exit code when a log of the batch failed (could not be read or fitted).
pub const EXIT_FAILED: u8 = 4;
/// Exit code when a fit is untrusted (as `greybox fit`).
pub const EXIT_UNTRUSTED: u8 = 3;

/// Runs `greybox fit --each PATTERN`; returns the exit code (see the module doc).
///
/// # Errors
/// [`Error::InvalidOption`] naming `--each` when nothing matches or the glob is malformed,
/// naming `--method` for `--method ls`, naming `--summary`/`--trend` for an output that
/// cannot be written (checked before any fit); the errors of [`plan`]; [`Error::Write`]
/// when an output cannot be written after the fits.
pub fn run_batch(a: &FitArgs, pattern: &str) -> crate::Result<u8> {
    let t0 = Instant::now();
    let request = FitRequest::from(a);
    let plan = batch_plan(&request)?;
    let paths = expand(pattern)?;
    let summary_paths = a.summary.as_deref().map(summary_paths);
    let (csv, json) =
        (summary_paths.as_ref().map(|s| s.0.as_path()), summary_paths.as_ref().map(|s| s.1.as_path()));
    output::check_all(&[("--summary", csv), ("--summary", json), ("--trend", a.trend.as_deref())], &paths)?;
    let stems: Vec<String> = paths.iter().map(|p| stem(p)).collect();
    let names = crate::app::unique_names(&paths, &stems);
    let bar = progress(a.quiet, paths.len());
    let threads = rayon::current_num_threads();
    let records =
        fit_each(&request, &plan, &paths, &names, threads, super::errors::in_fit_words, |path, result| {
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
    fn summary_paths_drop_a_given_extension() {
        let (c, j) = summary_paths(Path::new("out/sum.json"));
        assert_eq!((c, j), (PathBuf::from("out/sum.csv"), PathBuf::from("out/sum.json")));
        let (c, _) = summary_paths(Path::new("out/sum.v2"));
        assert_eq!(c, PathBuf::from("out/sum.v2.csv"));
    }
}
