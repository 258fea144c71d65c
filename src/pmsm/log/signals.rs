//! The PMSM view of an experiment: dq voltages and currents, speed and angle under their
//! channel names, with typed access that names a missing channel.
//!
//! Conventions (MODEL.md §1, §4): currents and voltages are amplitude-invariant dq
//! quantities (`|i_dq|` = phase peak), `u[k]` is the terminal voltage averaged over
//! `[t_k, t_k + h)`, speeds and angles are **mechanical**.

use crate::data::{Channel, Experiment, Values};
use crate::error::{Error, Result};

/// Channel names of a PMSM log, as the CSV defaults and [`DqSignals`] write them.
pub mod channel {
    /// d-axis terminal voltage, period mean over `[t_k, t_k + h)` \[V\].
    pub const U_D: &str = "ud";
    /// q-axis terminal voltage, period mean \[V\].
    pub const U_Q: &str = "uq";
    /// d-axis current at `t_k` \[A, peak\].
    pub const I_D: &str = "id";
    /// q-axis current at `t_k` \[A, peak\].
    pub const I_Q: &str = "iq";
    /// Mechanical rotor speed at `t_k` \[rad/s\].
    pub const W_M: &str = "w_m";
    /// Mechanical rotor angle at `t_k` \[rad\].
    pub const THETA_M: &str = "theta_m";
    /// d-axis voltage reference computed at `t_k` \[V\].
    pub const U_D_REF: &str = "ud_ref";
    /// q-axis voltage reference computed at `t_k` \[V\].
    pub const U_Q_REF: &str = "uq_ref";
}

/// Fewest samples of a PMSM log: 16 residuals (two outputs) for at most 6 unknowns of a
/// dynamic fit (3–4 parameters and 2 initial states), whose intervals are then wide and
/// say so. Slow telemetry can be this short: every 5000th row of a 7 s log at 10 kHz
/// holds 15 (it was 16 before slow telemetry from drive cycles was fitted).
pub const MIN_SAMPLES: usize = 8;

/// Raw signals of one PMSM log before validation; all vectors have one entry per sample.
///
/// Units: `u_d, u_q, u_d_ref, u_q_ref` \[V\], `i_d, i_q` \[A, peak\], `w_m` \[rad/s, mechanical\],
/// `theta_m` \[rad, mechanical\].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DqSignals {
    /// d-axis terminal voltage, period mean over `[t_k, t_k + h)` \[V\], length N; empty when
    /// the log carries only the voltage reference (`u_d_ref`, `u_q_ref`).
    pub u_d: Vec<f64>,
    /// q-axis terminal voltage, period mean over `[t_k, t_k + h)` \[V\], length N; empty as
    /// `u_d`.
    pub u_q: Vec<f64>,
    /// d-axis current at `t_k` \[A, peak\], length N.
    pub i_d: Vec<f64>,
    /// q-axis current at `t_k` \[A, peak\], length N.
    pub i_q: Vec<f64>,
    /// Mechanical rotor speed at `t_k` \[rad/s\], length N.
    pub w_m: Vec<f64>,
    /// Mechanical rotor angle at `t_k` \[rad\], length N, if logged.
    pub theta_m: Option<Vec<f64>>,
    /// d-axis voltage reference computed at `t_k` \[V\], length N, if logged.
    pub u_d_ref: Option<Vec<f64>>,
    /// q-axis voltage reference computed at `t_k` \[V\], length N, if logged.
    pub u_q_ref: Option<Vec<f64>>,
}

impl DqSignals {
    /// The signals as channels under the names of [`channel`], optional ones when present.
    pub fn into_channels(self) -> Vec<Channel> {
        let terminal = !(self.u_d.is_empty() && self.u_q.is_empty());
        let mut c: Vec<Channel> = terminal
            .then(|| [Channel::new(channel::U_D, "V", self.u_d), Channel::new(channel::U_Q, "V", self.u_q)])
            .into_iter()
            .flatten()
            .collect();
        c.extend([
            Channel::new(channel::I_D, "A", self.i_d),
            Channel::new(channel::I_Q, "A", self.i_q),
            Channel::new(channel::W_M, "rad/s", self.w_m),
        ]);
        let optional = [
            (channel::THETA_M, "rad", self.theta_m),
            (channel::U_D_REF, "V", self.u_d_ref),
            (channel::U_Q_REF, "V", self.u_q_ref),
        ];
        c.extend(optional.into_iter().filter_map(|(n, u, v)| Some(Channel::new(n, u, v?))));
        c
    }

    /// A validated PMSM experiment sampled every `h` \[s\].
    ///
    /// # Errors
    /// Those of [`Experiment::try_new`] (naming the channel and row), and
    /// [`Error::TooShort`] below [`MIN_SAMPLES`].
    pub fn into_experiment(self, name: impl Into<String>, h: f64) -> Result<Experiment> {
        let e = Experiment::try_new(name, h, self.into_channels())?;
        DqView::try_new(&e)?;
        Ok(e)
    }
}

/// Typed, borrowed access to the PMSM channels of an [`Experiment`].
#[derive(Clone, Copy, Debug)]
pub struct DqView<'a> {
    e: &'a Experiment,
    terminal: Option<(&'a [f64], &'a [f64])>,
    i_d: &'a [f64],
    i_q: &'a [f64],
    w_m: &'a Values,
}

impl<'a> DqView<'a> {
    /// The view of `e`.
    ///
    /// # Errors
    /// [`Error::MissingChannel`] naming the first of `id, iq, w_m` that `e` lacks, or `ud`
    /// / `uq` when `e` has neither the terminal voltage nor the reference (`ud_ref`,
    /// `uq_ref`); [`Error::TooShort`] below [`MIN_SAMPLES`] samples.
    pub fn try_new(e: &'a Experiment) -> Result<Self> {
        let terminal = match (e.get(channel::U_D), e.get(channel::U_Q)) {
            (Some(d), Some(q)) => Some((d.values.as_slice(), q.values.as_slice())),
            _ if e.get(channel::U_D_REF).is_some() && e.get(channel::U_Q_REF).is_some() => None,
            _ => Some((e.channel(channel::U_D)?, e.channel(channel::U_Q)?)),
        };
        let v = Self {
            e,
            terminal,
            i_d: e.channel(channel::I_D)?,
            i_q: e.channel(channel::I_Q)?,
            w_m: e.values(channel::W_M)?,
        };
        if e.len() < MIN_SAMPLES {
            return Err(Error::TooShort { name: e.name().into(), len: e.len(), min: MIN_SAMPLES });
        }
        Ok(v)
    }
    /// The experiment viewed.
    pub fn experiment(&self) -> &'a Experiment {
        self.e
    }
    /// Sample time h \[s\].
    pub fn h(&self) -> f64 {
        self.e.h()
    }
    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.e.len()
    }
    /// Always false: a view holds at least [`MIN_SAMPLES`] samples.
    pub fn is_empty(&self) -> bool {
        self.e.is_empty()
    }
    /// The terminal voltage `(u_d, u_q)`, period means \[V\], each of length N.
    ///
    /// # Errors
    /// [`Error::MissingChannel`] (`ud`) for a log that carries only the voltage reference.
    pub fn terminal_voltage(&self) -> Result<(&'a [f64], &'a [f64])> {
        match self.terminal {
            Some(u) => Ok(u),
            None => Err(self.e.channel(channel::U_D).err().unwrap_or_else(|| Error::MissingChannel {
                experiment: self.e.name().into(),
                channel: channel::U_D.into(),
                available: String::new(),
            })),
        }
    }
    /// [`terminal_voltage`](Self::terminal_voltage) `(u_d, u_q)` \[V\], length N each, as the
    /// experiment's shared channels (cloning them shares the samples).
    ///
    /// # Errors
    /// As [`terminal_voltage`](Self::terminal_voltage).
    pub fn shared_terminal_voltage(&self) -> Result<(&'a Values, &'a Values)> {
        self.terminal_voltage()?;
        Ok((self.e.values(channel::U_D)?, self.e.values(channel::U_Q)?))
    }
    /// [`w_m`](Self::w_m) \[rad/s\], length N, as the experiment's shared channel (cloning
    /// it shares the samples).
    pub fn shared_w_m(&self) -> &'a Values {
        self.w_m
    }
    /// d-axis current at `t_k` \[A, peak\], length N.
    pub fn i_d(&self) -> &'a [f64] {
        self.i_d
    }
    /// q-axis current at `t_k` \[A, peak\], length N.
    pub fn i_q(&self) -> &'a [f64] {
        self.i_q
    }
    /// Mechanical speed at `t_k` \[rad/s\], length N.
    pub fn w_m(&self) -> &'a [f64] {
        self.w_m.as_slice()
    }
    /// Largest current magnitude `max_k |i_dq[k]|` \[A, peak\] (`hypot` of each sample).
    pub fn peak_current(&self) -> f64 {
        // The largest squared magnitude first (a loop that vectorises), then `hypot` of the
        // samples whose square is within rounding of it (or not finite): the same maximum
        // as `hypot` of every sample.
        let (d, q) = (self.i_d, self.i_q);
        let squares = || d.iter().zip(q).map(|(d, q)| d * d + q * q);
        let largest = squares().fold(0.0, f64::max);
        // Below 1e-290 a square is subnormal or close to it and its rounding no longer
        // relative; an infinite one hides the finite ones: every sample's hypot there.
        let threshold =
            if (1e-290..=f64::MAX).contains(&largest) { largest * (1.0 - 1e-12) } else { f64::NEG_INFINITY };
        squares()
            .zip(d.iter().zip(q))
            .filter(|(s, _)| *s >= threshold || s.is_nan())
            .map(|(_, (d, q))| d.hypot(*q))
            .fold(0.0, f64::max)
    }
    /// Mechanical angle at `t_k` \[rad\], length N, if logged.
    pub fn theta_m(&self) -> Option<&'a [f64]> {
        self.e.get(channel::THETA_M).map(|c| c.values.as_slice())
    }
    /// d- and q-axis voltage references \[V\], length N each, if both are logged.
    pub fn u_dq_ref(&self) -> Option<(&'a [f64], &'a [f64])> {
        Some((&self.e.get(channel::U_D_REF)?.values, &self.e.get(channel::U_Q_REF)?.values))
    }
    /// The signals copied out (to edit and rebuild an experiment).
    pub fn to_signals(&self) -> DqSignals {
        let opt = |n: &str| self.e.get(n).map(|c| c.values.to_vec());
        DqSignals {
            u_d: self.terminal.map(|u| u.0.to_vec()).unwrap_or_default(),
            u_q: self.terminal.map(|u| u.1.to_vec()).unwrap_or_default(),
            i_d: self.i_d.to_vec(),
            i_q: self.i_q.to_vec(),
            w_m: self.w_m.to_vec(),
            theta_m: opt(channel::THETA_M),
            u_d_ref: opt(channel::U_D_REF),
            u_q_ref: opt(channel::U_Q_REF),
        }
    }
}

/// Largest plausible number of pole pairs n_p: 100 (large direct-drive and wind
/// generators reach a few tens; more is a typo or a speed in the wrong unit).
pub const MAX_POLE_PAIRS: u32 = 100;

/// The errors only a motor has, inside [`Error::Domain`] (`err.domain::<PmsmError>()`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PmsmError {
    /// The number of pole pairs is outside `1..=`[`MAX_POLE_PAIRS`] (or none was given
    /// where the log's speed or dq currents need it).
    #[error("number of pole pairs n_p must be in 1..=100, got {n_p}")]
    InvalidPolePairs {
        /// The value given (0 for none).
        n_p: u32,
    },
}

impl From<PmsmError> for Error {
    fn from(e: PmsmError) -> Self {
        Error::Domain(Box::new(e))
    }
}

/// Checks a pole-pair number: `1 ≤ n_p ≤` [`MAX_POLE_PAIRS`].
///
/// # Errors
/// [`PmsmError::InvalidPolePairs`] for `n_p = 0` or `n_p > 100`.
pub(crate) fn check_pole_pairs(n_p: u32) -> Result<()> {
    if (1..=MAX_POLE_PAIRS).contains(&n_p) { Ok(()) } else { Err(PmsmError::InvalidPolePairs { n_p }.into()) }
}
