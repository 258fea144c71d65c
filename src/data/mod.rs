//! Experiment data: named signal channels sampled at `t_k = k h`, validated once on
//! construction.
//!
//! An [`Experiment`] is a sample time plus any number of [`Channel`]s, each a name, a unit
//! and one value per sample. Nothing here knows what a channel means: a model declares the
//! channels it reads and predicts ([`crate::model::GreyBoxModel`]), and a domain view
//! (e.g. [`crate::pmsm::DqView`] for motor logs) gives typed access that errors with the
//! missing channel's name. Units are converted to SI at the edge (the CSV readers), never
//! inside the library.

pub mod columnar;
pub mod csv;
pub mod segments;
pub mod write;

pub use segments::{GAP_FACTOR, TimeWindow, is_gap};

use crate::error::{Error, Result};

/// Minimum number of samples of an [`Experiment`]: one. Models and estimators check what
/// they need themselves (a static regression needs `n_θ + 1` observations, a dynamic model
/// at least two samples).
pub const MIN_SAMPLES: usize = 1;

/// A channel's values, shared: cloning an [`Experiment`], or preparing a fit on it,
/// shares the samples instead of copying them (a fit's memory beyond the data stays
/// O(n_θ²) where its model reads the channels as they are). Build one from a `Vec<f64>`
/// with `.into()`; [`std::sync::Arc::make_mut`] edits it (copying only if it is shared).
pub type Values = std::sync::Arc<Vec<f64>>;

/// One named signal: values at `t_k` (or period means over `[t_k, t_k + h)`, as the
/// channel's documentation says), length N.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Channel name, e.g. `ud`, `w_m`, `temperature`.
    pub name: String,
    /// SI unit, e.g. `V`, `rad/s`, `K`; empty for dimensionless.
    pub unit: String,
    /// One value per sample, length N (shared, see [`Values`]).
    pub values: Values,
}

impl Channel {
    /// A channel called `name` in `unit` with the given values (not yet validated: that
    /// happens when an [`Experiment`] is built from it).
    pub fn new(name: impl Into<String>, unit: impl Into<String>, values: Vec<f64>) -> Self {
        Self { name: name.into(), unit: unit.into(), values: values.into() }
    }
}

/// One validated log: a name, the sample time h \[s\] and its channels.
///
/// Invariants checked by [`Experiment::try_new`]: h positive and finite, at least one
/// channel, channel names unique, every channel of equal length N ≥ [`MIN_SAMPLES`] and
/// every value finite.
#[derive(Clone, Debug, PartialEq)]
pub struct Experiment {
    name: String,
    h: f64,
    channels: Vec<Channel>,
}

impl Experiment {
    /// Validates `channels` sampled every `h` \[s\].
    ///
    /// # Errors
    /// [`Error::InvalidSampleTime`] for `h ≤ 0` or non-finite; [`Error::TooShort`] for no
    /// channel or fewer than [`MIN_SAMPLES`] samples; [`Error::DuplicateChannel`] naming a
    /// repeated channel; [`Error::LengthMismatch`] naming the first channel whose length
    /// differs from the first channel's; [`Error::NonFinite`] naming the channel and row of
    /// the first NaN/Inf.
    pub fn try_new(name: impl Into<String>, h: f64, channels: Vec<Channel>) -> Result<Self> {
        let name = name.into();
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidSampleTime { h });
        }
        let n = channels.first().map_or(0, |c| c.values.len());
        for (i, c) in channels.iter().enumerate() {
            if channels[..i].iter().any(|d| d.name == c.name) {
                return Err(Error::DuplicateChannel { experiment: name, channel: c.name.clone() });
            }
            if c.values.len() != n {
                return Err(Error::LengthMismatch {
                    column: c.name.clone(),
                    expected: n,
                    found: c.values.len(),
                });
            }
        }
        if n < MIN_SAMPLES {
            return Err(Error::TooShort { name, len: n, min: MIN_SAMPLES });
        }
        for c in channels.iter().filter(|c| !all_finite(&c.values)) {
            if let Some((row, &value)) = c.values.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                return Err(Error::NonFinite { column: c.name.clone(), row, value });
            }
        }
        Ok(Self { name, h, channels })
    }

    /// Like [`Experiment::try_new`], with the sample time taken from a time vector `t` \[s\].
    ///
    /// `t` must be strictly increasing and uniform: every step within [`TIME_TOLERANCE`]
    /// (relative) of the mean step `h = (t[N−1] − t[0])/(N − 1)`, and `t[k]` within `h/2`
    /// of `t[0] + k h`. A single sample has no step and is refused.
    ///
    /// # Errors
    /// Those of [`Experiment::try_new`], plus [`Error::NonUniformTime`] naming `time_name`
    /// and the row of the first non-increasing or irregular step ([`TimeSteps`]), and
    /// [`Error::NonFinite`]/[`Error::LengthMismatch`]/[`Error::TooShort`] for the time
    /// vector itself.
    pub fn try_from_time(
        name: impl Into<String>,
        time_name: &str,
        t: &[f64],
        channels: Vec<Channel>,
    ) -> Result<Self> {
        let name = name.into();
        if let Some(c) = channels.iter().find(|c| c.values.len() != t.len()) {
            return Err(Error::LengthMismatch {
                column: c.name.clone(),
                expected: t.len(),
                found: c.values.len(),
            });
        }
        if t.len() < 2 {
            return Err(Error::TooShort { name, len: t.len(), min: 2 });
        }
        let h = uniform_step(t, time_name)?;
        Self::try_new(name, h, channels)
    }

    /// Name of the experiment (the log's file stem when read from a file).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Sample time h \[s\].
    pub fn h(&self) -> f64 {
        self.h
    }
    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, |c| c.values.len())
    }
    /// Always false: a valid experiment holds at least [`MIN_SAMPLES`] samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// All channels, in the order given.
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }
    /// The channel called `name`, if present.
    pub fn get(&self, name: &str) -> Option<&Channel> {
        self.channels.iter().find(|c| c.name == name)
    }
    /// Values of the channel called `name`, length N.
    ///
    /// # Errors
    /// [`Error::MissingChannel`] naming the experiment, the channel and the channels present.
    pub fn channel(&self, name: &str) -> Result<&[f64]> {
        self.values(name).map(|v| v.as_slice())
    }
    /// The error for a channel `name` the experiment lacks.
    fn missing(&self, name: &str) -> Error {
        Error::MissingChannel {
            experiment: self.name.clone(),
            channel: name.into(),
            available: self.channels.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", "),
        }
    }
    /// The shared values of the channel called `name`, length N (cloning them shares the
    /// samples: see [`Values`]).
    ///
    /// # Errors
    /// As [`Experiment::channel`].
    pub fn values(&self, name: &str) -> Result<&Values> {
        self.get(name).map(|c| &c.values).ok_or_else(|| self.missing(name))
    }
    /// The experiment with `channel` added, or replacing the channel of the same name.
    ///
    /// # Errors
    /// As [`Experiment::try_new`] for the new channel (length, finiteness).
    pub fn with_channel(mut self, channel: Channel) -> Result<Self> {
        self.channels.retain(|c| c.name != channel.name);
        self.channels.push(channel);
        Self::try_new(self.name, self.h, self.channels)
    }
    /// The same experiment under another name.
    pub fn renamed(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }
    /// Returns the experiment restricted to samples `range` (for splitting logs).
    ///
    /// # Errors
    /// [`Error::TooShort`] for an empty range, [`Error::InvalidOption`] if it lies outside
    /// `0..N`.
    pub fn slice(&self, range: std::ops::Range<usize>) -> Result<Self> {
        if range.end > self.len() || range.start > range.end {
            return Err(Error::InvalidOption {
                option: "range".into(),
                reason: format!("{range:?} is outside 0..{}", self.len()),
            });
        }
        let channels = self
            .channels
            .iter()
            .map(|c| Channel::new(c.name.clone(), c.unit.clone(), c.values[range.clone()].to_vec()))
            .collect();
        Self::try_new(self.name.clone(), self.h, channels)
    }
}

/// Uniformity tolerance of a time column, relative to the step h: every step
/// `t[k] − t[k−1]` must lie within `0.25 h` of the mean step h, and every `t[k]` within
/// `h/2` of `t[0] + k h`.
///
/// The first test names the row of a dropped, repeated or shifted sample; the second
/// catches a slow drift of the rate. Both admit the rounding of times written with 6
/// decimals at any rate up to 100 kHz.
pub const TIME_TOLERANCE: f64 = 0.25;

/// Whether a table reader ([`csv::read_table_with`], [`columnar::read_table_with`]) checks
/// the time column (the first wanted column) with [`TimeSteps::push`] while the rows
/// stream in. Default [`TimeCheck::Streaming`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeCheck {
    /// The reader checks the time column row by row and stops at the first bad step
    /// ([`Error::NonUniformTime`]), as [`csv::read_table`] always does. The default.
    #[default]
    Streaming,
    /// The reader reads the time column as any other wanted column (each value a finite
    /// number, else [`Error::NonFinite`] naming it) and leaves its steps unchecked: for a
    /// caller that checks them itself, e.g. one that keeps a window of the rows or cuts the
    /// column at its gaps ([`segments::time_segments`]).
    Skip,
}

/// Incremental check of a time column `t_k` \[s\], one row at a time, so that a reader can
/// stop at the first bad row instead of after the whole file; [`TimeSteps::finish`] then
/// applies the checks that need the mean step h of the whole column.
///
/// Row by row ([`TimeSteps::push`]): every value finite ([`Error::NonFinite`]), every step
/// positive, and every step within `[0.6, 5/3]` of the mean of the steps before it
/// ([`Error::NonUniformTime`], reported with [`TIME_TOLERANCE`]). A column that passes
/// [`TIME_TOLERANCE`] against its mean h has every step and every partial mean within
/// `[0.75 h, 1.25 h]`, so the row-by-row test never refuses a column the final one accepts;
/// it only names a grossly dropped or repeated sample early (a repeated row at row 1).
/// A gap ([`is_gap`]) is an error here like any other bad step (its message says so and
/// how to split the log); [`segments::time_segments`] cuts a column at its gaps instead.
#[derive(Clone, Debug)]
pub struct TimeSteps {
    column: String,
    first: f64,
    last: f64,
    rows: usize,
}

impl TimeSteps {
    /// A checker for the time column called `column` (the name the errors carry).
    pub fn new(column: impl Into<String>) -> Self {
        Self { column: column.into(), first: 0.0, last: 0.0, rows: 0 }
    }

    /// Number of values pushed.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Checks the next value `t` \[s\], of 0-based row [`TimeSteps::rows`].
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/Inf; [`Error::NonUniformTime`] for a step that is not
    /// positive (with the mean step so far as `expected`) or is far from the mean of the
    /// earlier steps.
    pub fn push(&mut self, t: f64) -> Result<()> {
        let row = self.rows;
        if !t.is_finite() {
            return Err(Error::NonFinite { column: self.column.clone(), row, value: t });
        }
        if row > 0 {
            let dt = t - self.last;
            let bad = |expected: f64| Error::NonUniformTime {
                column: self.column.clone(),
                row,
                dt,
                expected,
                tolerance: TIME_TOLERANCE,
            };
            if dt <= 0.0 {
                return Err(bad((t - self.first) / row as f64));
            }
            if row > 1 {
                let before = (self.last - self.first) / (row - 1) as f64;
                if !(0.6 * before..=before / 0.6).contains(&dt) {
                    return Err(bad(before));
                }
            }
        } else {
            self.first = t;
        }
        self.last = t;
        self.rows += 1;
        Ok(())
    }

    /// Mean step h = `(t[N−1] − t[0])/(N − 1)` \[s\] of the column whose N values were pushed,
    /// after the checks that need it: every step within [`TIME_TOLERANCE`] h of h and every
    /// `t[k]` within `h/2` of `t[0] + k h`. `t` is the column itself.
    ///
    /// # Errors
    /// [`Error::InvalidSampleTime`] for fewer than two values or a non-finite h;
    /// [`Error::NonUniformTime`] naming the first row outside either bound.
    pub fn finish(&self, t: &[f64]) -> Result<f64> {
        let n = t.len();
        if n < 2 {
            return Err(Error::InvalidSampleTime { h: f64::NAN });
        }
        let h = (t[n - 1] - t[0]) / (n - 1) as f64;
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidSampleTime { h });
        }
        let bad = |row: usize| Error::NonUniformTime {
            column: self.column.clone(),
            row,
            dt: t[row] - t[row - 1],
            expected: h,
            tolerance: TIME_TOLERANCE,
        };
        if let Some(k) = (1..n).find(|&k| ((t[k] - t[k - 1]) - h).abs() > TIME_TOLERANCE * h) {
            return Err(bad(k));
        }
        if let Some(k) = (1..n).find(|&k| (t[k] - (t[0] + k as f64 * h)).abs() > 0.5 * h) {
            return Err(bad(k));
        }
        Ok(h)
    }
}

/// Mean step of a uniform, strictly increasing time vector (N ≥ 2), checked sample by
/// sample with [`TimeSteps`].
fn uniform_step(t: &[f64], column: &str) -> Result<f64> {
    let mut steps = TimeSteps::new(column);
    t.iter().try_for_each(|&x| steps.push(x))?;
    steps.finish(t)
}

/// Whether every value of `c` is finite: `v · 0` is NaN exactly for a non-finite v, summed
/// in four independent lanes so that the loop vectorises (no branch per value; a caller
/// then seeks the first bad value only where there is one).
#[inline]
pub(crate) fn all_finite(c: &[f64]) -> bool {
    let mut acc = [0.0f64; 4];
    let mut chunks = c.chunks_exact(4);
    for q in &mut chunks {
        for l in 0..4 {
            acc[l] += q[l] * 0.0;
        }
    }
    let tail: f64 = chunks.remainder().iter().map(|v| v * 0.0).sum();
    !(acc[0] + acc[1] + acc[2] + acc[3] + tail).is_nan()
}
