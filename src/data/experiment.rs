//! One validated log: [`Experiment`], a sample time h and channels of equal length, checked
//! once on construction.

use super::channel::{Channel, Values, all_finite};
use super::time::uniform_step;
use crate::error::{Error, Result};

/// Minimum number of samples of an [`Experiment`]: one. Models and estimators check what
/// they need themselves (a static regression needs `n_θ + 1` observations, a dynamic model
/// at least two samples).
pub const MIN_SAMPLES: usize = 1;

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
    /// Time of the first sample \[s\] in the log's own clock (0 unless set).
    t0: f64,
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
        Ok(Self { name, h, channels, t0: 0.0 })
    }

    /// Like [`Experiment::try_new`], with the sample time taken from a time vector `t` \[s\].
    ///
    /// `t` must be strictly increasing and uniform: every step within [`TIME_TOLERANCE`](super::TIME_TOLERANCE)
    /// (relative) of the mean step `h = (t[N−1] − t[0])/(N − 1)`, and `t[k]` within `h/2`
    /// of `t[0] + k h`. A single sample has no step and is refused.
    ///
    /// # Errors
    /// Those of [`Experiment::try_new`], plus [`Error::NonUniformTime`] naming `time_name`
    /// and the row of the first non-increasing or irregular step ([`TimeSteps`](super::TimeSteps)), and
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
        Ok(Self::try_new(name, h, channels)?.with_t0(t[0]))
    }

    /// Name of the experiment (the log's file stem when read from a file).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Sample time h \[s\].
    pub fn h(&self) -> f64 {
        self.h
    }
    /// Time of the first sample \[s\] in the log's own clock (its time column's first value;
    /// 0 for an experiment built without one): sample k is at `t0 + k h`, the time that
    /// reports, residual exports and plots give it.
    pub fn t0(&self) -> f64 {
        self.t0
    }
    /// The same experiment with its first sample at `t0` \[s\] (a finite value; any other
    /// leaves it as it was).
    pub fn with_t0(mut self, t0: f64) -> Self {
        if t0.is_finite() {
            self.t0 = t0;
        }
        self
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
        Ok(Self::try_new(self.name.clone(), self.h, channels)?.with_t0(self.t0 + range.start as f64 * self.h))
    }

    /// Every `factor`-th sample (point samples from the first on, as a slow logger reads a
    /// drive's latest values; no averaging), sample time `factor h`, named `NAME /factor`.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `factor`) for 0; [`Error::TooShort`] when fewer
    /// samples than an experiment needs remain.
    pub fn decimate(&self, factor: usize) -> Result<Self> {
        if factor == 0 {
            return Err(Error::InvalidOption {
                option: "factor".into(),
                reason: "0 keeps no sample; give 1 or more".into(),
            });
        }
        let channels = self
            .channels
            .iter()
            .map(|c| {
                Channel::new(
                    c.name.clone(),
                    c.unit.clone(),
                    c.values.iter().step_by(factor).copied().collect(),
                )
            })
            .collect();
        Ok(Self::try_new(format!("{} /{factor}", self.name), self.h * factor as f64, channels)?
            .with_t0(self.t0))
    }
}
