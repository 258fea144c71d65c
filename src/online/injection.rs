//! The d-current injection that lets the MRAS adapt `R_s` under `i_d = 0` control
//! (thesis 5.1.1: "an injection of direct current every ten minutes or so", no longer than
//! about one second; MODEL.md §6).

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// A periodic d-current pulse: `i_d_amplitude` \[A\] for `duration_s` \[s\] at the start of
/// every `period_s` \[s\], zero otherwise. Add its [`InjectionSchedule::i_d_reference`] to the
/// drive's d-current reference.
///
/// Default: 1 s every 600 s (thesis 5.1.1) with amplitude 0 A: the amplitude is motor
/// dependent (thesis Exp 1 used 20 % of the q-current reference) and must be set.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct InjectionSchedule {
    /// Period between the starts of two pulses \[s\], positive.
    pub period_s: f64,
    /// Length of one pulse \[s\], in `[0, period_s]`.
    pub duration_s: f64,
    /// d-current of the pulse \[A, peak dq\], finite (either sign).
    pub i_d_amplitude: f64,
}

impl Default for InjectionSchedule {
    fn default() -> Self {
        Self { period_s: 600.0, duration_s: 1.0, i_d_amplitude: 0.0 }
    }
}

impl InjectionSchedule {
    /// A validated schedule.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming `period_s` (not positive and finite), `duration_s`
    /// (outside `[0, period_s]`) or `i_d_amplitude` (not finite).
    pub fn try_new(period_s: f64, duration_s: f64, i_d_amplitude: f64) -> Result<Self> {
        let s = Self { period_s, duration_s, i_d_amplitude };
        s.validate()?;
        Ok(s)
    }

    /// Checks the fields; see [`InjectionSchedule::try_new`].
    ///
    /// # Errors
    /// As [`InjectionSchedule::try_new`].
    pub fn validate(&self) -> Result<()> {
        let bad = |option: &str, reason: String| Err(Error::InvalidOption { option: option.into(), reason });
        if !(self.period_s.is_finite() && self.period_s > 0.0) {
            return bad("period_s", format!("must be positive and finite, got {}", self.period_s));
        }
        if !(self.duration_s >= 0.0 && self.duration_s <= self.period_s) {
            return bad(
                "duration_s",
                format!("must lie in [0, period_s = {}], got {}", self.period_s, self.duration_s),
            );
        }
        if !self.i_d_amplitude.is_finite() {
            return bad("i_d_amplitude", format!("must be finite, got {}", self.i_d_amplitude));
        }
        Ok(())
    }

    /// Whether a pulse is on at time `t` \[s\] (`t mod period_s < duration_s`); false for
    /// negative or non-finite `t` and for an invalid schedule.
    pub fn is_injecting(&self, t: f64) -> bool {
        if !(t.is_finite() && t >= 0.0 && self.period_s.is_finite() && self.period_s > 0.0) {
            return false;
        }
        t.rem_euclid(self.period_s) < self.duration_s
    }

    /// The d-current reference \[A\] at time `t` \[s\]: `i_d_amplitude` during a pulse, 0
    /// otherwise (see [`InjectionSchedule::is_injecting`]).
    pub fn i_d_reference(&self, t: f64) -> f64 {
        if self.is_injecting(t) { self.i_d_amplitude } else { 0.0 }
    }
}
