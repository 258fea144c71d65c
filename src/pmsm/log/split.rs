//! A log split at the gaps of its time column into segments, each its own experiment.

use std::path::Path;

use super::options::CsvOptions;
use super::plausible::plausible;
use super::reader::{LogSource, Raw};
use crate::data::{Experiment, TimeCheck};
use crate::error::{Error, Result};
use crate::pmsm::log::signals::MIN_SAMPLES;

/// One log read by [`read_log_segments`]: its segments long enough to fit, and the others.
#[derive(Clone, Debug, PartialEq)]
pub struct LogSegments {
    /// The log's name (the file name without `.csv.gz` …), as [`read_log`](super::read_log)
    /// names its experiment.
    pub name: String,
    /// The segments of at least [`MIN_SAMPLES`] samples, in file order; named `name` when
    /// there is one, else `name#1`, `name#2`, … in that order.
    pub experiments: Vec<Experiment>,
    /// The segments too short to fit, in file order.
    pub dropped: Vec<DroppedSegment>,
}

/// A segment of a log left out by [`read_log_segments`] because it is too short to fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DroppedSegment {
    /// Time of its first sample \[s\].
    pub from: f64,
    /// Time of its last sample \[s\].
    pub to: f64,
    /// Number of samples, below [`MIN_SAMPLES`].
    pub samples: usize,
}

/// Reads one PMSM drive log as [`read_log`](super::read_log) does, but split at the gaps
/// of its time column into segments that become separate experiments (to be fitted
/// jointly: each has its own initial state).
///
/// The time column (in `options.time_unit`, converted to seconds) is first cut to
/// `options.window`, then split before every row whose step from the previous row is a
/// gap ([`crate::data::is_gap`]: not positive, or longer than
/// [`GAP_FACTOR`](crate::data::GAP_FACTOR) = 1.5 times the median step of the rows in
/// the window) and wherever the window leaves out rows in between. Each segment must then
/// be uniform on its own ([`Experiment::try_from_time`]); its h is its own mean step.
/// A segment of fewer than [`MIN_SAMPLES`] samples (the minimum
/// [`read_log`](super::read_log) accepts for a whole log, so that a segment is fitted
/// exactly when it would be as a file of its own) is left out and listed in
/// [`LogSegments::dropped`]. A log without gaps gives one experiment, equal to
/// [`read_log`](super::read_log)'s. The segments are copies of rows of the log; row
/// numbers in errors count the file's data rows from 0.
///
/// # Errors
/// Those of [`read_log`](super::read_log) but the gap error: for a window holding too few
/// samples, a segment that is not uniform (a step neither regular nor a gap: between 1.25 h
/// and 1.5 h, or positive below 0.75 h), a segment with an implausible sample time; and
/// [`Error::InvalidOption`] with option `split_gaps` when no segment holds
/// [`MIN_SAMPLES`] samples (naming how many segments there are and the longest).
///
/// ```no_run
/// use greybox::pmsm::{read_log_segments, CsvOptions};
/// let log = read_log_segments("run.csv", &CsvOptions::default())?;
/// for d in &log.dropped {
///     eprintln!("left out: {} samples from {} s to {} s", d.samples, d.from, d.to);
/// }
/// println!("{} segments", log.experiments.len());
/// # Ok::<(), greybox::Error>(())
/// ```
pub fn read_log_segments(path: impl AsRef<Path>, options: &CsvOptions) -> Result<LogSegments> {
    read_log_segments_from(LogSource::Path(path.as_ref()), options)
}

/// [`read_log_segments`] of a file or an Arrow table in memory (see [`read_log_from`](super::read_log_from)).
///
/// # Errors
/// Those of [`read_log_segments`], naming the table's name where they name a path.
pub fn read_log_segments_from(source: LogSource<'_>, options: &CsvOptions) -> Result<LogSegments> {
    let path = source.path();
    let raw = Raw::read(source, options, TimeCheck::Skip)?;
    let cut = raw.window(options)?;
    let t = raw.t();
    let (kept, short): (Vec<_>, Vec<_>) = cut.segments.into_iter().partition(|s| s.len() >= MIN_SAMPLES);
    let dropped: Vec<DroppedSegment> = short
        .into_iter()
        .map(|s| DroppedSegment { from: t[s.start], to: t[s.end - 1], samples: s.len() })
        .collect();
    if kept.is_empty() {
        let longest = dropped.iter().map(|d| d.samples).max().unwrap_or(0);
        return Err(Error::InvalidOption {
            option: "split_gaps".into(),
            reason: format!(
                "{} splits at its gaps into {} segments, none of at least {MIN_SAMPLES} samples (the longest has {longest})",
                path.display(),
                dropped.len()
            ),
        });
    }
    let name = raw.name.clone();
    let experiments = if let [range] = &kept[..] {
        // One segment (the common case of a log without gaps): its rows cut in place.
        vec![plausible(path, raw.into_experiment(range.clone(), options)?, options)?]
    } else {
        kept.into_iter()
            .enumerate()
            .map(|(k, range)| {
                let e = raw.build(range, format!("{name}#{}", k + 1), options)?;
                plausible(path, e, options)
            })
            .collect::<Result<Vec<_>>>()?
    };
    Ok(LogSegments { name, experiments, dropped })
}
