//! Experiment data: the signals of one drive log, validated once on construction.
//!
//! An [`Experiment`] holds the dq voltages and currents, the mechanical speed and,
//! optionally, the mechanical angle and the controller's voltage references, all sampled
//! at `t_k = k h`. Conventions (MODEL.md §1, §4): currents and voltages are
//! amplitude-invariant dq quantities (`|i_dq|` = phase peak), `u[k]` is the terminal
//! voltage averaged over `[t_k, t_k + h)`, speeds and angles are **mechanical**.

pub mod csv;
pub mod transform;

use crate::error::{Error, Result};

/// Minimum number of samples an [`Experiment`] must hold.
pub const MIN_SAMPLES: usize = 16;

/// Raw signals of one log before validation; all vectors have one entry per sample.
///
/// Units: `u_d, u_q, u_d_ref, u_q_ref` [V], `i_d, i_q` [A, peak], `w_m` [rad/s, mechanical],
/// `theta_m` [rad, mechanical].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Signals {
    /// d-axis terminal voltage, period mean over `[t_k, t_k + h)` [V], length N.
    pub u_d: Vec<f64>,
    /// q-axis terminal voltage, period mean over `[t_k, t_k + h)` [V], length N.
    pub u_q: Vec<f64>,
    /// d-axis current at `t_k` [A, peak], length N.
    pub i_d: Vec<f64>,
    /// q-axis current at `t_k` [A, peak], length N.
    pub i_q: Vec<f64>,
    /// Mechanical rotor speed at `t_k` [rad/s], length N.
    pub w_m: Vec<f64>,
    /// Mechanical rotor angle at `t_k` [rad], length N, if logged.
    pub theta_m: Option<Vec<f64>>,
    /// d-axis voltage reference computed at `t_k` [V], length N, if logged.
    pub u_d_ref: Option<Vec<f64>>,
    /// q-axis voltage reference computed at `t_k` [V], length N, if logged.
    pub u_q_ref: Option<Vec<f64>>,
}

/// One validated drive log: signals, sample time and pole-pair number.
///
/// Invariants checked by [`Experiment::try_new`]: every signal finite and of equal length
/// N ≥ [`MIN_SAMPLES`], `h` positive and finite, `n_p ≥ 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct Experiment {
    name: String,
    h: f64,
    n_p: u32,
    s: Signals,
}

impl Experiment {
    /// Validates `signals` sampled every `h` [s] on a machine with `n_p` pole pairs.
    ///
    /// # Errors
    /// [`Error::InvalidSampleTime`] for `h ≤ 0` or non-finite, [`Error::InvalidPolePairs`]
    /// for `n_p = 0`, [`Error::LengthMismatch`] naming the first signal whose length differs
    /// from `u_d`'s, [`Error::TooShort`] below [`MIN_SAMPLES`], [`Error::NonFinite`] naming
    /// the signal and row of the first NaN/Inf.
    pub fn try_new(name: impl Into<String>, h: f64, n_p: u32, signals: Signals) -> Result<Self> {
        let name = name.into();
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidSampleTime { h });
        }
        if n_p == 0 {
            return Err(Error::InvalidPolePairs { n_p });
        }
        let n = signals.u_d.len();
        for (col, v) in named(&signals) {
            if v.len() != n {
                return Err(Error::LengthMismatch { column: col.to_string(), expected: n, found: v.len() });
            }
        }
        if n < MIN_SAMPLES {
            return Err(Error::TooShort { name, len: n, min: MIN_SAMPLES });
        }
        for (col, v) in named(&signals) {
            if let Some((row, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                return Err(Error::NonFinite { column: col.to_string(), row, value });
            }
        }
        Ok(Self { name, h, n_p, s: signals })
    }

    /// Like [`Experiment::try_new`], with the sample time taken from a time vector `t` [s].
    ///
    /// `t` must be strictly increasing and uniform: every step within [`TIME_TOLERANCE`]
    /// (relative) of the mean step `h = (t[N−1] − t[0])/(N − 1)`, and `t[k]` within `h/2`
    /// of `t[0] + k h`.
    ///
    /// # Errors
    /// Those of [`Experiment::try_new`], plus [`Error::NonUniformTime`] naming the column
    /// and the row of the first non-increasing or irregular step, and
    /// [`Error::NonFinite`]/[`Error::LengthMismatch`] for the `t` column itself.
    pub fn try_from_time(name: impl Into<String>, t: &[f64], n_p: u32, signals: Signals) -> Result<Self> {
        let name = name.into();
        if t.len() != signals.u_d.len() {
            return Err(Error::LengthMismatch {
                column: "t".into(),
                expected: signals.u_d.len(),
                found: t.len(),
            });
        }
        if t.len() < MIN_SAMPLES {
            return Err(Error::TooShort { name, len: t.len(), min: MIN_SAMPLES });
        }
        if let Some((row, &value)) = t.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return Err(Error::NonFinite { column: "t".into(), row, value });
        }
        let h = uniform_step(t, "t")?;
        Self::try_new(name, h, n_p, signals)
    }

    /// Name of the experiment (the log's file stem when read from a file).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Sample time h [s].
    pub fn h(&self) -> f64 {
        self.h
    }
    /// Number of pole pairs n_p (electrical speed `w_e = n_p w_m`).
    pub fn n_p(&self) -> u32 {
        self.n_p
    }
    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.s.u_d.len()
    }
    /// Always false: a valid experiment holds at least [`MIN_SAMPLES`] samples.
    pub fn is_empty(&self) -> bool {
        self.s.u_d.is_empty()
    }
    /// All signals.
    pub fn signals(&self) -> &Signals {
        &self.s
    }
    /// d-axis terminal voltage, period means [V], length N.
    pub fn u_d(&self) -> &[f64] {
        &self.s.u_d
    }
    /// q-axis terminal voltage, period means [V], length N.
    pub fn u_q(&self) -> &[f64] {
        &self.s.u_q
    }
    /// d-axis current at `t_k` [A, peak], length N.
    pub fn i_d(&self) -> &[f64] {
        &self.s.i_d
    }
    /// q-axis current at `t_k` [A, peak], length N.
    pub fn i_q(&self) -> &[f64] {
        &self.s.i_q
    }
    /// Mechanical speed at `t_k` [rad/s], length N.
    pub fn w_m(&self) -> &[f64] {
        &self.s.w_m
    }
    /// Mechanical angle at `t_k` [rad], length N, if logged.
    pub fn theta_m(&self) -> Option<&[f64]> {
        self.s.theta_m.as_deref()
    }
    /// Electrical speed over interval k, `w_e = n_p (w_m[k] + w_m[k+1])/2` [rad/s], for
    /// `k < N − 1` (MODEL.md §4: speed at the interval mean).
    ///
    /// # Panics
    /// If `k ≥ N − 1`.
    pub fn w_e_interval(&self, k: usize) -> f64 {
        0.5 * f64::from(self.n_p) * (self.s.w_m[k] + self.s.w_m[k + 1])
    }
    /// Returns the experiment restricted to samples `range` (for splitting logs).
    ///
    /// # Errors
    /// [`Error::TooShort`] if the range holds fewer than [`MIN_SAMPLES`] samples,
    /// [`Error::InvalidOption`] if it lies outside `0..N`.
    pub fn slice(&self, range: std::ops::Range<usize>) -> Result<Self> {
        if range.end > self.len() || range.start > range.end {
            return Err(Error::InvalidOption {
                option: "range".into(),
                reason: format!("{range:?} is outside 0..{}", self.len()),
            });
        }
        let cut = |v: &Vec<f64>| v[range.clone()].to_vec();
        let s = &self.s;
        let signals = Signals {
            u_d: cut(&s.u_d),
            u_q: cut(&s.u_q),
            i_d: cut(&s.i_d),
            i_q: cut(&s.i_q),
            w_m: cut(&s.w_m),
            theta_m: s.theta_m.as_ref().map(cut),
            u_d_ref: s.u_d_ref.as_ref().map(cut),
            u_q_ref: s.u_q_ref.as_ref().map(cut),
        };
        Self::try_new(self.name.clone(), self.h, self.n_p, signals)
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

/// Mean step of a uniform, strictly increasing time vector, checked sample by sample.
fn uniform_step(t: &[f64], column: &str) -> Result<f64> {
    let n = t.len();
    let bad = |row: usize, expected: f64| Error::NonUniformTime {
        column: column.to_string(),
        row,
        dt: t[row] - t[row - 1],
        expected,
        tolerance: TIME_TOLERANCE,
    };
    if let Some(k) = (1..n).find(|&k| t[k] <= t[k - 1]) {
        return Err(bad(k, (t[n - 1] - t[0]) / (n - 1) as f64));
    }
    let h = (t[n - 1] - t[0]) / (n - 1) as f64;
    if !(h.is_finite() && h > 0.0) {
        return Err(Error::InvalidSampleTime { h });
    }
    if let Some(k) = (1..n).find(|&k| ((t[k] - t[k - 1]) - h).abs() > TIME_TOLERANCE * h) {
        return Err(bad(k, h));
    }
    if let Some(k) = (1..n).find(|&k| (t[k] - (t[0] + k as f64 * h)).abs() > 0.5 * h) {
        return Err(bad(k, h));
    }
    Ok(h)
}

fn named(s: &Signals) -> Vec<(&'static str, &Vec<f64>)> {
    let mut v = vec![("ud", &s.u_d), ("uq", &s.u_q), ("id", &s.i_d), ("iq", &s.i_q), ("w_m", &s.w_m)];
    if let Some(x) = &s.theta_m {
        v.push(("theta_m", x));
    }
    if let Some(x) = &s.u_d_ref {
        v.push(("ud_ref", x));
    }
    if let Some(x) = &s.u_q_ref {
        v.push(("uq_ref", x));
    }
    v
}
