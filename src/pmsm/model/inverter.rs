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

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::PemOptions;
use crate::model::Parameter;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::C64;
pub use crate::pmsm::model::mask::DeadTimeMask;
use crate::pmsm::model::mask::DeadTimeMaskWeighting;
pub(crate) use directions::WINDOW;
use serde::{Deserialize, Serialize};

mod directions;

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
    let theta_m = v.experiment().channel(crate::pmsm::channel::THETA_M)?;
    let mut stream = DeadTimeStream::try_new(v, n_p, model)?;
    let mut out = vec![C64::default(); v.len().saturating_sub(1)];
    stream.directions(theta_m, v.i_d(), v.i_q(), &mut out);
    stream.check_crossings()?;
    Ok(out)
}

/// The dead-time directions of [`dead_time_directions`] a part at a time, for passes that
/// store nothing per sample: [`directions`](Self::directions) of every part of the record
/// in order, and [`check_crossings`](Self::check_crossings) at the end. The arithmetic is
/// that of [`dead_time_directions`], bit for bit, however the
/// record is cut into windows (each interval's direction depends on its two samples only),
/// except for a stream [`for_check`](Self::for_check), whose functions are `wide`'s.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DeadTimeStream {
    /// Width w of the smooth sign \[A\].
    width: f64,
    /// Pole pairs n_p.
    np: f64,
    /// Smallest and largest current of each phase seen \[A\].
    lo: [f64; 3],
    hi: [f64; 3],
    /// The dead-time check's arithmetic (`wide`'s vectorised functions, within a few ulps
    /// of the library's) instead of the models'.
    check: bool,
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
        Ok(Self {
            width,
            np: f64::from(n_p),
            lo: [f64::INFINITY; 3],
            hi: [f64::NEG_INFINITY; 3],
            check: false,
        })
    }

    /// The stream with the dead-time check's arithmetic: sines, cosines and `tanh` by
    /// `wide`'s vectorised functions, within a few ulps of the library's (the check's
    /// verdict and printed percentage do not see the difference) in about a fifth of the
    /// time. Not for a model: its estimates would move in the last bits.
    pub(crate) fn for_check(self) -> Self {
        Self { check: true, ..self }
    }

    /// The dq error per unit `V_dt` \[V/V\] of each interval between consecutive samples of
    /// the mechanical angle `theta_m` \[rad\] and the dq current `i_d`, `i_q` \[A\] (m + 1
    /// samples each, m = `out.len()`) into `out`, rotated by the angle at the interval's
    /// start; each phase's range is recorded. The phase currents are the inverse Park
    /// transform at `θ_e = n_p θ_m`, the sign `tanh` of their interval mean over the width,
    /// sines, cosines and tangents the system library's (`wide`'s for a stream
    /// [`for_check`](Self::for_check)); [`WINDOW`] intervals at a time.
    ///
    /// # Panics
    /// When a slice is shorter than `out.len() + 1`.
    pub(crate) fn directions(&mut self, theta_m: &[f64], i_d: &[f64], i_q: &[f64], out: &mut [C64]) {
        for (k0, out) in (0..).step_by(WINDOW).zip(out.chunks_mut(WINDOW)) {
            let n = out.len() + 1;
            let (theta_m, i_d, i_q) = (&theta_m[k0..k0 + n], &i_d[k0..k0 + n], &i_q[k0..k0 + n]);
            let mut phases = [[0.0; WINDOW + 1]; 3];
            let mut sc = [(0.0, 0.0); WINDOW + 1];
            match self.check {
                false => directions::angles(self.np, theta_m, &mut sc[..n]),
                true => directions::angles_check(self.np, theta_m, &mut sc[..n]),
            }
            directions::phases(i_d, i_q, &sc[..n], &mut phases);
            for (x, (lo, hi)) in self.lo.iter_mut().zip(self.hi.iter_mut()).enumerate() {
                let p = &phases[x][..n];
                *lo = p.iter().copied().fold(*lo, f64::min);
                *hi = p.iter().copied().fold(*hi, f64::max);
            }
            match self.check {
                false => directions::signs(self.width, &phases, &sc[..n], out),
                true => directions::signs_check(self.width, &phases, &sc[..n], out),
            }
        }
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
