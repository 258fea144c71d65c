//! Reading the logs of a fit as asked ([`LogReading`]): one experiment per log, or its
//! segments when split at gaps, named by their file; the reader's errors with the file
//! (and the line of a CSV row) in front and its options named as the command line does.

use super::request::LogReading;
use crate::Experiment;
use crate::pmsm::{CsvOptions, LogSegments, LogSource};
use std::path::{Path, PathBuf};

/// Reads `paths` with `csv` (the reading's options, pole pairs set): one experiment per log,
/// or with `split_gaps` one per segment, named `LOG#1`, `LOG#2`, … (a log without gaps keeps
/// its name). `unique`: each log named by [`super::unique_names`], else by its file stem. A
/// dropped segment is reported on stderr with its time span. Grouped by log, in the order of
/// `paths`.
///
/// # Errors
/// Those of [`read_segments_from`].
pub fn read_logs(
    paths: &[PathBuf],
    csv: &CsvOptions,
    split_gaps: bool,
    unique: bool,
) -> crate::Result<Vec<Vec<Experiment>>> {
    let logs = paths
        .iter()
        .map(|p| read_segments_from(LogSource::Path(p), csv, split_gaps))
        .collect::<crate::Result<Vec<_>>>()?;
    let stems: Vec<String> = logs.iter().map(|l| l.name.clone()).collect();
    let names = if unique { super::logs::unique_names(paths, &stems) } else { stems };
    Ok(logs.into_iter().zip(names).zip(paths).map(|((log, name), path)| named(path, log, &name)).collect())
}

/// Reads one log (a file or an Arrow table in memory) with `csv`: one experiment, or with
/// `split_gaps` its segments (named by the reader; see [`named`]).
///
/// # Errors
/// The reader's, with the options named by their flags (`--from`, `--to`, `--from/--to`,
/// `--split-gaps`), a table named by its name.
pub fn read_segments_from(
    source: LogSource<'_>,
    csv: &CsvOptions,
    split_gaps: bool,
) -> crate::Result<LogSegments> {
    let log = if split_gaps {
        crate::pmsm::read_log_segments_from(source, csv)
    } else {
        crate::pmsm::read_log_from(source, csv).map(|e| LogSegments {
            name: e.name().to_string(),
            experiments: vec![e],
            dropped: vec![],
        })
    };
    let file = matches!(source, LogSource::Path(_));
    log.map_err(flag_words).map_err(|e| with_file(source.path(), e, csv.delimiter, file))
}

/// Reads the logs of a fit from `sources` as `greybox fit LOG...` reads its files (segments
/// with `reading.split_gaps`), with `csv` (the reading's options as planned): files named by
/// [`super::unique_names`] among the files, a table by its name; the paths checked first
/// ([`super::check_paths`]).
///
/// # Errors
/// Those of [`super::check_paths`] and [`read_segments_from`].
pub fn read_sources(
    reading: &LogReading,
    csv: &CsvOptions,
    sources: &[LogSource<'_>],
) -> crate::Result<Vec<Experiment>> {
    let paths: Vec<PathBuf> = sources
        .iter()
        .filter_map(|s| match s {
            LogSource::Path(p) => Some(p.to_path_buf()),
            #[allow(unreachable_patterns)]
            _ => None,
        })
        .collect();
    super::logs::check_paths(&paths)?;
    let mut segments = Vec::with_capacity(sources.len());
    for s in sources {
        segments.push(read_segments_from(*s, csv, reading.split_gaps)?);
    }
    let file_stems: Vec<String> = sources
        .iter()
        .zip(&segments)
        .filter(|(s, _)| matches!(s, LogSource::Path(_)))
        .map(|(_, l)| l.name.clone())
        .collect();
    let mut file_names = super::logs::unique_names(&paths, &file_stems).into_iter();
    Ok(sources
        .iter()
        .zip(segments)
        .flat_map(|(s, log)| {
            let name = match s {
                LogSource::Path(_) => file_names.next().unwrap_or_else(|| log.name.clone()),
                #[allow(unreachable_patterns)]
                _ => log.name.clone(),
            };
            named(s.path(), log, &name)
        })
        .collect())
}

/// A data error that names no file (a non-finite value, a time step, a length) with the
/// log's path in front, as the parse errors have it, and for a row of a CSV log (`file`:
/// not a table in memory) the line of the file it stands on.
fn with_file(path: &Path, e: crate::Error, delimiter: crate::data::Delimiter, file: bool) -> crate::Error {
    use crate::Error;
    let line = match &e {
        Error::NonFinite { row, .. }
        | Error::NonUniformTime { row, .. }
        | Error::ImplausibleValue { row, .. }
            if file =>
        {
            csv_line(path, *row, delimiter)
        }
        _ => None,
    };
    let at = line.map(|l| format!(" (line {l} of the file)")).unwrap_or_default();
    match e {
        Error::NonFinite { .. }
        | Error::ImplausibleValue { .. }
        | Error::NonUniformTime { .. }
        | Error::LengthMismatch { .. }
        | Error::InvalidSampleTime { .. } => {
            Error::Format { path: path.to_path_buf(), message: format!("{e}{at}") }
        }
        other => other,
    }
}

/// The experiments of `log` (read from `path`) named `name`, or `name#1`, `name#2`, … when
/// it was split into segments; its dropped segments reported on stderr with their span.
pub fn named(path: &Path, log: LogSegments, name: &str) -> Vec<Experiment> {
    for d in &log.dropped {
        eprintln!(
            "warning: {}: the segment from t = {} s to {} s ({} samples, fewer than {}) is dropped, not fitted",
            path.display(),
            d.from,
            d.to,
            d.samples,
            crate::pmsm::MIN_SAMPLES
        );
    }
    let one = log.experiments.len() == 1;
    let segment = |k: usize, e: Experiment| {
        if one { e.renamed(name) } else { e.renamed(format!("{name}#{}", k + 1)) }
    };
    log.experiments.into_iter().enumerate().map(|(k, e)| segment(k, e)).collect()
}

/// The reader's option names as the flags that set them.
fn flag_words(e: crate::Error) -> crate::Error {
    match e {
        crate::Error::InvalidOption { option, reason } => {
            let flag = match option.as_str() {
                "from" => "--from",
                "to" => "--to",
                "window" => "--from/--to",
                "split_gaps" => "--split-gaps",
                _ => return crate::Error::InvalidOption { option, reason },
            };
            crate::Error::InvalidOption { option: flag.into(), reason }
        }
        other => other,
    }
}

/// The 1-based line of the file on which data row `row` (0-based, header excluded) of the
/// CSV log at `path` starts (gzip for `.gz`), read again with the `csv` crate on the error
/// path; `None` for a columnar log or when the file cannot be read so far.
fn csv_line(path: &Path, row: usize, delimiter: crate::data::Delimiter) -> Option<u64> {
    use crate::data::Format;
    if Format::of(path) != Format::Csv {
        return None;
    }
    let file = std::fs::File::open(path).ok()?;
    let gz = path.extension().is_some_and(|x| x == "gz");
    let reader: Box<dyn std::io::Read> =
        if gz { Box::new(flate2::read::GzDecoder::new(file)) } else { Box::new(file) };
    let mut csv = csv::ReaderBuilder::new().delimiter(delimiter.byte()).flexible(true).from_reader(reader);
    let mut record = csv::ByteRecord::new();
    for _ in 0..=row {
        if !csv.read_byte_record(&mut record).ok()? {
            return None;
        }
    }
    record.position().map(|p| p.line())
}
