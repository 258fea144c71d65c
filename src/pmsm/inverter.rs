//! The inverter's voltage error as a nuisance input (MODEL.md §4): dead time and device
//! on-state drop make each phase voltage fall short of the reference by about
//! `V_dt sign(i_x)`, `x = a, b, c` (`V_dt ≈ t_d f_sw U_dc + V_on`). Per unit `V_dt` the error
//! is a data-only dq vector per interval; the models scale it by the estimated `v_dt`.
//!
//! A current-dependent device drop `V_on + r_on |i_x|` adds `−r_on |i_x| sign(i_x) = −r_on i_x`
//! per phase, which is `−r_on i_dq` in dq: exactly the form of `R_s`, so no log can separate
//! `r_on` from the winding resistance. A known `r_on` is a series resistance: give it with
//! the cable's (`cable_resistance`, `--cable-resistance`), and `r_s` is the motor's alone.
//!
//! Sign near zero current: `tanh(i_x / w)` with width `w` \[A\] (the ripple and the
//! parasitic capacitances blur the switch-over). The error is held in the stator frame over
//! the period, like the voltage the modulator applies, so the exact stator-hold step stays
//! exact with it.

use super::interval::C64;
pub use super::mask::DeadTimeMask;
use super::signals::DqView;
use super::transform::{clarke, inverse_clarke};
use crate::error::{Error, Result};
use crate::model::Parameter;
use serde::{Deserialize, Serialize};

/// Default sign width, relative to the largest current magnitude of the log.
pub const DEFAULT_RELATIVE_WIDTH: f64 = 0.02;

/// The inverter error model: per-phase `−V_dt tanh(i_x/w)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
pub struct InverterModel {
    /// Width w of the smooth sign \[A\]; `None`: [`DEFAULT_RELATIVE_WIDTH`] × the largest
    /// `|i_dq|` of the log, or a tenth of the [`DeadTimeMask`] threshold.
    pub width: Option<f64>,
    /// A known `V_dt` \[V\], held fixed; `None`: estimated (from 0).
    pub known: Option<f64>,
    /// Periods with a phase current near zero weighted out ([`DeadTimeMask`]); `None`: all
    /// periods kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<DeadTimeMask>,
}

/// The nuisance parameter `v_dt` \[V\]: the per-phase voltage error, non-negative.
pub fn v_dt_parameter() -> Parameter {
    Parameter { lower: 0.0, nuisance: true, ..Parameter::free("v_dt", "V", 1.0) }
}

/// Per interval `k = 0..N−2`, the dq voltage error per unit `V_dt` at the start of the
/// period \[V/V\]: `−park(clarke(tanh(ī_a/w), tanh(ī_b/w), tanh(ī_c/w)), θ_e[k])` with `ī_x`
/// the interval mean of the phase currents (each sample's dq current rotated by its own
/// `θ_e = n_p θ_m`).
///
/// # Errors
/// [`Error::MissingChannel`] when the log has no `theta_m`; [`Error::InvalidOption`] for a
/// width that is not positive and finite; [`Error::Numerical`] naming the phase whose
/// current never changes sign (its error is then a constant offset, not separable from the
/// other parameters: `V_dt` unidentifiable).
pub fn dead_time_directions(v: &DqView<'_>, n_p: u32, model: &InverterModel) -> Result<Vec<C64>> {
    let theta_m = v.experiment().channel(super::channel::THETA_M)?;
    let mut stream = DeadTimeStream::try_new(v, n_p, model)?;
    let (id, iq) = (v.i_d(), v.i_q());
    let samples: Vec<([f64; 3], (f64, f64))> = (0..v.len())
        .map(|k| {
            let sc = stream.angle(theta_m[k]);
            (stream.phases(id[k], iq[k], sc), sc)
        })
        .collect();
    stream.check_crossings()?;
    Ok(samples.windows(2).map(|w| stream.direction(w[0].0, w[1].0, w[0].1)).collect())
}

/// The dead-time directions of [`dead_time_directions`] one sample at a time, for passes that
/// store nothing per sample: [`angle`](Self::angle) and [`phases`](Self::phases) at every
/// sample in order, [`direction`](Self::direction) of each interval, and
/// [`check_crossings`](Self::check_crossings) at the end. The arithmetic is that of
/// [`dead_time_directions`], bit for bit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DeadTimeStream {
    /// Width w of the smooth sign \[A\].
    width: f64,
    /// Pole pairs n_p.
    np: f64,
    /// Smallest and largest current of each phase seen \[A\].
    lo: [f64; 3],
    hi: [f64; 3],
}

impl DeadTimeStream {
    /// The stream of `v` under `model` (its width resolved as [`InverterModel::width`] says).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] for a width that is not positive and finite.
    pub(crate) fn try_new(v: &DqView<'_>, n_p: u32, model: &InverterModel) -> Result<Self> {
        // With the mask, every kept period has its phase currents clear of zero: a sign 10 times
        // sharper than the threshold is the sign there.
        let width = model.width.unwrap_or(match model.mask {
            Some(DeadTimeMask::Current(t)) if t > 0.0 => 0.1 * t,
            _ => DEFAULT_RELATIVE_WIDTH * v.peak_current(),
        });
        if !(width.is_finite() && width > 0.0) {
            return Err(Error::InvalidOption {
                option: "dead-time width".into(),
                reason: format!("{width} A must be positive and finite (all-zero currents?)"),
            });
        }
        Ok(Self { width, np: f64::from(n_p), lo: [f64::INFINITY; 3], hi: [f64::NEG_INFINITY; 3] })
    }

    /// `(sin θ_e, cos θ_e)` of the mechanical angle `theta_m` \[rad\].
    #[inline]
    pub(crate) fn angle(&self, theta_m: f64) -> (f64, f64) {
        (self.np * theta_m).sin_cos()
    }

    /// Phase currents `(i_a, i_b, i_c)` \[A\] of a sample from its dq current and
    /// [`angle`](Self::angle); each phase's range is recorded.
    #[inline]
    pub(crate) fn phases(&mut self, i_d: f64, i_q: f64, (s, c): (f64, f64)) -> [f64; 3] {
        // inverse_park, with the angle's sine and cosine given.
        let (i_a, i_b, i_c) = inverse_clarke(c * i_d - s * i_q, s * i_d + c * i_q);
        let p = [i_a, i_b, i_c];
        for ((lo, hi), x) in self.lo.iter_mut().zip(self.hi.iter_mut()).zip(p) {
            *lo = lo.min(x);
            *hi = hi.max(x);
        }
        p
    }

    /// The dq error per unit `V_dt` of the interval from phase currents `p` to `q`, rotated
    /// by the [`angle`](Self::angle) `sc` at its start \[V/V\].
    #[inline]
    pub(crate) fn direction(&self, p: [f64; 3], q: [f64; 3], (s, c): (f64, f64)) -> C64 {
        let sign = |x: f64, y: f64| -smooth_sign((0.5 * (x + y)) / self.width);
        let (alpha, beta) = clarke(sign(p[0], q[0]), sign(p[1], q[1]), sign(p[2], q[2]));
        // park, with the angle's sine and cosine given.
        C64::new(c * alpha + s * beta, -s * alpha + c * beta)
    }

    /// # Errors
    /// [`Error::Numerical`] naming the first phase whose current never crossed zero by more
    /// than the width (its error is then a constant offset: `V_dt` unidentifiable).
    pub(crate) fn check_crossings(&self) -> Result<()> {
        let width = self.width;
        for (x, name) in [0, 1, 2].into_iter().zip(["a", "b", "c"]) {
            let (lo, hi) = (self.lo[x], self.hi[x]);
            if !(hi > width && lo < -width) {
                return Err(Error::Numerical {
                    context: "dead-time model".into(),
                    reason: format!(
                        "the current of phase {name} (range [{lo:.3e}, {hi:.3e}] A) never crosses zero by more than \
                         {width:.3e} A: the dead-time \
                         voltage is then a constant offset the data cannot separate from the motor's parameters \
                         (fix v_dt, or use a log with current reversals)"
                    ),
                });
            }
        }
        Ok(())
    }
}

/// `tanh(x)`, without calling it where it is ±1 to the last bit (`|x| ≥ 19.5`:
/// `1 − tanh|x| < 2e^{−39} < 2⁻⁵⁴`, below half an ulp of 1).
#[inline]
fn smooth_sign(x: f64) -> f64 {
    if x.abs() >= 19.5 { x.signum() } else { x.tanh() }
}
