//! The dead-time mask: the periods in which a phase current is near zero are weighted out of
//! a fit driven by the voltage *reference* with the inverter model.
//!
//! Why: a PWM leg's dead-time error is `−V_dt sign(i_x)` with the sign of the current *at the
//! leg's switching instant*, not at the sample (the carrier-comparison modulator of
//! motulator, `common/model/_pwm.py`, and every hard-switched two-level inverter: Mohan,
//! Undeland and Robbins, *Power Electronics*, 3rd ed., §8.6.2). Within about 1 A of zero the
//! switching ripple and the dead-time pulse itself decide that sign, and 10 kHz samples cannot
//! reconstruct it: on the PWM log of the development data, 20 % of such phase periods get the
//! wrong sign at speed (±11 V each), which biased `l_s` by +8 % and `k_e` by +0.65 %. Clear of
//! zero the error is `−V_dt sign(i_x)` to 0.06 V rms. So the mask keeps a period only when
//! every phase current keeps its sign over it and stays at least `threshold` away from zero
//! at both ends; the fit is then a one-step-ahead prediction (k = 1), which restarts from the
//! measured current and so never carries a masked period's wrong voltage into a kept one.
//!
//! Threshold: the current excursion of one dead-time pulse is `U_dc t_d / L ≈ 2h (V_dt − V_on)
//! / L` (switching frequency `1/(2h)`, double update), and the ripple at the switching
//! instant is of the same order; [`DeadTimeMask::Auto`] takes `4 h V_dt / L` (twice the pulse
//! bound) from the fit itself, by fixed-point iteration from the unmasked fit.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::Weighting;
use crate::pmsm::log::signals::channel;
use crate::pmsm::log::transform::{inverse_clarke, inverse_park};
use serde::{Deserialize, Serialize};

/// Threshold iterations of [`DeadTimeMask::Auto`] after the unmasked fit.
pub(crate) const AUTO_ITERATIONS: usize = 2;

/// Which periods the dead-time mask weights out.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeadTimeMask {
    /// Threshold `4 h V_dt / L` from the fit (see the module documentation).
    Auto,
    /// A threshold \[A\]: periods in which a phase current comes closer to zero are dropped.
    Current(f64),
}

/// A weighting rule that zeroes the residual at sample k when, over the period `[t_{k−1},
/// t_k]`, some phase current changes sign or comes within `threshold` of zero at either end,
/// and keeps the `inner` rule's weights elsewhere.
#[derive(Debug)]
pub struct DeadTimeMaskWeighting<'a> {
    /// The rule for the other samples.
    pub inner: &'a dyn Weighting,
    /// Pole pairs n_p (`θ_e = n_p θ_m`).
    pub n_p: u32,
    /// Threshold \[A\].
    pub threshold: f64,
}

impl DeadTimeMaskWeighting<'_> {
    /// Phase currents `(i_a, i_b, i_c)` \[A\] at sample k, `None` without the channels.
    fn phases(&self, e: &Experiment, k: usize) -> Option<[f64; 3]> {
        let (id, iq, th) = (e.get(channel::I_D)?, e.get(channel::I_Q)?, e.get(channel::THETA_M)?);
        let (a, b) = inverse_park(id.values[k], iq.values[k], f64::from(self.n_p) * th.values[k]);
        let (x, y, z) = inverse_clarke(a, b);
        Some([x, y, z])
    }

    /// Whether the period ending at sample k has a phase current near or through zero.
    pub(crate) fn masked(&self, e: &Experiment, k: usize) -> bool {
        let (Some(j), true) = (k.checked_sub(1), k < e.len()) else { return false };
        let (Some(p), Some(q)) = (self.phases(e, j), self.phases(e, k)) else { return false };
        p.iter().zip(&q).any(|(a, b)| a * b <= 0.0 || a.abs().min(b.abs()) < self.threshold)
    }

    /// Number of samples of `e` weighted out.
    pub fn count(&self, e: &Experiment) -> usize {
        (0..e.len()).filter(|&k| self.masked(e, k)).count()
    }
}

impl Weighting for DeadTimeMaskWeighting<'_> {
    fn name(&self) -> String {
        format!(
            "{} without periods with a phase current within {:.3} A of zero",
            self.inner.name(),
            self.threshold
        )
    }
    fn sample_weight(&self, e: &Experiment, k: usize) -> f64 {
        if self.masked(e, k) { 0.0 } else { self.inner.sample_weight(e, k) }
    }
    fn output_weights(&self) -> Option<Vec<f64>> {
        self.inner.output_weights()
    }
    fn check(&self, e: &Experiment) -> Result<()> {
        e.channel(channel::THETA_M)?;
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return Err(Error::InvalidOption {
                option: "dead-time mask".into(),
                reason: format!("{} A must be non-negative and finite", self.threshold),
            });
        }
        let kept = e.len() - self.count(e);
        if kept < crate::pmsm::log::signals::MIN_SAMPLES {
            return Err(Error::Numerical {
                context: "dead-time mask".into(),
                reason: format!(
                    "`{}`: only {kept} samples have every phase current {:.3} A clear of zero; lower the \
                     threshold",
                    e.name(),
                    self.threshold
                ),
            });
        }
        self.inner.check(e)
    }
}
