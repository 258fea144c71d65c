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

use super::fit::{PmsmFit, PmsmFitOptions, fit_pmsm};
use super::inverter::InverterModel;
use super::signals::{DqView, channel};
use super::transform::{inverse_clarke, inverse_park};
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{PemOptions, Weighting};
use serde::{Deserialize, Serialize};

/// Threshold iterations of [`DeadTimeMask::Auto`] after the unmasked fit.
const AUTO_ITERATIONS: usize = 2;

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
    fn masked(&self, e: &Experiment, k: usize) -> bool {
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
        if kept < super::signals::MIN_SAMPLES {
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

/// Per sample of `e`, whether a fit with `inverter` counted it (length N): false where its
/// [`DeadTimeMask::Current`] weighted the sample out; empty (every sample counts) without a
/// mask threshold.
pub(crate) fn counted(inverter: Option<&InverterModel>, n_p: u32, e: &Experiment) -> Vec<bool> {
    match inverter.and_then(|i| i.mask) {
        Some(DeadTimeMask::Current(threshold)) => {
            let mask = DeadTimeMaskWeighting { inner: &crate::estimate::weighting::Uniform, n_p, threshold };
            (0..e.len()).map(|k| !mask.masked(e, k)).collect()
        }
        _ => Vec::new(),
    }
}

/// The prediction-error options a masked fit uses: one-step-ahead prediction unless a
/// horizon is given, with the note that says so.
pub(crate) fn masked_pem(inverter: Option<&InverterModel>, pem: &PemOptions) -> (PemOptions, Option<String>) {
    match inverter.and_then(|i| i.mask) {
        Some(_) if pem.horizon.is_none() => (
            PemOptions { horizon: Some(1), ..pem.clone() },
            Some(
                "dead-time mask: one-step-ahead prediction (k = 1), so that the masked periods' voltage errors do \
                 not propagate into the kept ones"
                    .into(),
            ),
        ),
        _ => (pem.clone(), None),
    }
}

/// Threshold relative to the largest current magnitude of the logs when a fit gives no
/// positive `4 h V_dt / L` (e.g. `v_dt` at its bound 0 before the mask).
pub const FALLBACK_RELATIVE_THRESHOLD: f64 = 0.05;

/// `4 h V_dt / L` \[A\] from a fit (`h` the longest sample time of the logs, `L` the smallest
/// inductance estimate), or `None` when that is not positive and finite.
fn auto_threshold(experiments: &[Experiment], fit: &PmsmFit) -> Option<f64> {
    let h = experiments.iter().map(Experiment::h).fold(0.0, f64::max);
    let l = super::kind::smallest_inductance(fit);
    let v_dt = fit.parameter("v_dt").map_or(f64::NAN, |p| p.value);
    Some(4.0 * h * v_dt / l).filter(|t| t.is_finite() && *t > 0.0)
}

/// [`FALLBACK_RELATIVE_THRESHOLD`] × the largest `|i_dq|` of the logs \[A\].
fn fallback_threshold(experiments: &[Experiment]) -> Result<f64> {
    let peak = experiments
        .iter()
        .filter_map(|e| DqView::try_new(e).ok())
        .map(|v| v.peak_current())
        .fold(0.0, f64::max);
    Some(FALLBACK_RELATIVE_THRESHOLD * peak).filter(|t| t.is_finite() && *t > 0.0).ok_or_else(|| {
        Error::Numerical {
            context: "dead-time mask".into(),
            reason: "no threshold: the currents are all zero (give the threshold in amperes)".into(),
        }
    })
}

/// [`fit_pmsm`] with [`DeadTimeMask::Auto`]: the unmasked fit, then the threshold
/// `4 h V_dt / L` from the latest fit, twice; the report records the threshold used.
///
/// When a fit gives no positive `4 h V_dt / L` (its `v_dt` at 0), the threshold is
/// [`FALLBACK_RELATIVE_THRESHOLD`] of the peak current for that step.
///
/// # Errors
/// Those of [`fit_pmsm`]; [`Error::Numerical`] when the currents are all zero.
pub(crate) fn fit_auto_mask(experiments: &[Experiment], options: &PmsmFitOptions) -> Result<PmsmFit> {
    let inverter = options.inverter.unwrap_or_default();
    let with_mask = |mask: Option<DeadTimeMask>, start: Option<Vec<f64>>| PmsmFitOptions {
        inverter: Some(InverterModel { mask, ..inverter }),
        start: start.or_else(|| options.start.clone()),
        ..options.clone()
    };
    // The inner fits skip the setup checks; the last one runs them as `options` says.
    let mut fit =
        fit_pmsm(experiments, &PmsmFitOptions { skip_setup_checks: true, ..with_mask(None, None) })?;
    let mut trail = Vec::new();
    for step in 0..AUTO_ITERATIONS {
        let threshold = match auto_threshold(experiments, &fit) {
            Some(t) => t,
            None => {
                let t = fallback_threshold(experiments)?;
                trail.push(format!(
                    "(v_dt {:.3e} V: {:.0} % of the peak current)",
                    fit.parameter("v_dt").map_or(f64::NAN, |p| p.value),
                    100.0 * FALLBACK_RELATIVE_THRESHOLD
                ));
                t
            }
        };
        trail.push(format!("{threshold:.4}"));
        let names = options.model.parameter_names().iter().copied().chain(["v_dt"]);
        let start: Option<Vec<f64>> = names.map(|n| fit.parameter(n).map(|p| p.value)).collect();
        let last = step + 1 == AUTO_ITERATIONS;
        let o = with_mask(Some(DeadTimeMask::Current(threshold)), start);
        fit = fit_pmsm(
            experiments,
            &PmsmFitOptions { skip_setup_checks: !last || options.skip_setup_checks, ..o },
        )?;
    }
    let mut pmsm_notes = fit.pmsm_notes.clone();
    pmsm_notes.push(format!(
        "dead-time mask threshold 4 h v_dt / L by fixed-point iteration from the unmasked fit: {} A",
        trail.join(" → ")
    ));
    Ok(PmsmFit { pmsm_notes, ..fit })
}
