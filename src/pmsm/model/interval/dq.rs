//! The dq vector, the voltage's hold and input, and the data-only terms of a sample
//! interval that the surface- and interior-magnet models share (MODEL.md §2, §4).

use crate::error::{Error, Result};
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::elementary::sin_cos_small;
use nalgebra::Complex;
use serde::{Deserialize, Serialize};

/// How the voltage is held between samples (MODEL.md §4).
///
/// An inverter holds its output constant in the **stator** frame over a period, so in dq
/// it rotates backwards by `φ = ω_e h`; some simulators hold the **dq** voltage constant.
/// Each is exact for its source and wrong at second order in φ for the other.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum VoltageHold {
    /// `u_dq` constant over `[t_k, t_k + h)`.
    Dq,
    /// `u_αβ` constant over the period; `u[k]` is the period mean of the rotating dq voltage.
    #[default]
    Stator,
}

/// The observer crate's name of the same hold (its firmware core knows no `greybox` type).
impl From<VoltageHold> for greybox_observer::Hold {
    fn from(hold: VoltageHold) -> Self {
        match hold {
            VoltageHold::Dq => Self::Dq,
            VoltageHold::Stator => Self::Stator,
        }
    }
}

impl std::fmt::Display for VoltageHold {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Dq => "dq",
            Self::Stator => "stator",
        })
    }
}

/// Complex number of two `f64` (dq or αβ vector).
pub type C64 = Complex<f64>;

/// `√(2/3)`: back-EMF per K_e and mechanical speed (MODEL.md §2).
pub const SQRT_2_3: f64 = 0.816_496_580_927_726;

/// Interval-mean mechanical speed `(w_m[k] + w_m[k+1])/2` \[rad/s\] for `k = 0..N−2`,
/// length N − 1 (MODEL.md §4: the speed of the exact step).
pub fn interval_mean_speed(w_m: &[f64]) -> Vec<f64> {
    w_m.windows(2).map(mean_speed).collect()
}

/// The mean `(w[0] + w[1])/2` of the speeds at an interval's ends (`w` of length ≥ 2).
#[inline]
pub(crate) fn mean_speed(w: &[f64]) -> f64 {
    0.5 * (w[0] + w[1])
}

/// Rotation of the dq frame over one period, `e^{−jφ}` with `φ = ω_e h` \[rad\].
#[inline]
pub fn rotation(phi: f64) -> C64 {
    greybox_observer::rotation(phi)
}

/// Start-of-period dq voltage `u₀ = ū jφ/(1 − e^{−jφ})` of a stator-held voltage whose
/// dq period mean is `ū` (MODEL.md §4); the limit φ → 0 is `ū`.
#[inline]
pub fn stator_hold_start(mean: C64, phi: f64) -> C64 {
    greybox_observer::stator_hold_start(mean, phi)
}

/// [`stator_hold_start`] from `(sin φ/2, cos φ/2)` computed already (no further sine,
/// cosine or complex division): `jφ/(1 − e^{−jφ}) = (φ/2)/sin(φ/2) · e^{jφ/2}`, since
/// `1 − e^{−jφ} = 2j sin(φ/2) e^{−jφ/2}`; the same number to a few ulps (unit test).
#[inline]
pub(crate) fn stator_hold_start_half(mean: C64, phi: f64, sin_half: f64, cos_half: f64) -> C64 {
    // (φ/2)/sin(φ/2) = 1 + φ²/24 + …: 1 to the last bit below 1e-8.
    let gain = if phi.abs() < 1e-8 { 1.0 } else { 0.5 * phi / sin_half };
    mean * C64::new(gain * cos_half, gain * sin_half)
}

pub(crate) fn check_positive(name: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name: name.into(),
            value: v,
            reason: "must be positive and finite".into(),
        })
    }
}

pub(crate) fn check_finite(name: &str, v: f64) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(Error::InvalidParameter { name: name.into(), value: v, reason: "must be finite".into() })
    }
}

/// Data-only quantities of one sample interval, shared by the SPM and IPM models.
#[derive(Clone, Copy, Debug)]
pub struct Interval {
    /// Interval-mean electrical speed ω_e \[rad/s\].
    pub w_e: f64,
    /// `√(2/3)` × interval-mean mechanical speed \[rad/s\]: back-EMF per unit K_e.
    pub emf: f64,
    /// Rotation of the dq frame over the period, `e^{−jφ}`, `φ = ω_e h`.
    pub rot: C64,
    /// `1 − cos φ`, free of cancellation near 0.
    pub vers: f64,
    /// dq voltage at the start of the period \[V\]: `u[k]` (dq hold) or `u₀` (stator hold).
    pub u0: C64,
}

/// The intervals `k = 0..N−2` of a log on a machine with `n_p` pole pairs: interval-mean
/// speed, rotation and the start-of-period terminal voltage for the given hold (MODEL.md §4).
///
/// # Errors
/// [`Error::MissingChannel`] (`ud`) for a log that carries only the voltage reference.
pub fn intervals<'a>(
    v: &DqView<'a>,
    n_p: u32,
    hold: VoltageHold,
) -> Result<impl Iterator<Item = Interval> + 'a> {
    let (ud, uq) = v.terminal_voltage()?;
    let h = v.h();
    Ok(motion_half(v, n_p).enumerate().map(move |(k, (iv, sin_half, cos_half))| {
        let uk = C64::new(ud[k], uq[k]);
        let u0 = match hold {
            VoltageHold::Dq => uk,
            VoltageHold::Stator => stator_hold_start_half(uk, iv.w_e * h, sin_half, cos_half),
        };
        Interval { u0, ..iv }
    }))
}

/// The data-only part of the intervals (speed and rotation), with `u0 = 0`.
pub(super) fn motion<'a>(v: &DqView<'a>, n_p: u32) -> impl Iterator<Item = Interval> + 'a {
    motion_half(v, n_p).map(|(iv, _, _)| iv)
}

/// [`motion`] with `(sin φ/2, cos φ/2)` of each interval (see [`half_angle_rotation`]).
fn motion_half<'a>(v: &DqView<'a>, n_p: u32) -> impl Iterator<Item = (Interval, f64, f64)> + 'a {
    let h = v.h();
    let np = f64::from(n_p);
    let wm = v.w_m();
    wm.windows(2).map(move |w| {
        let w_m = mean_speed(w);
        let w_e = np * w_m;
        let (sin_half, cos_half) = half_angle(w_e, h);
        let (rot, vers) = half_angle_rotation(sin_half, cos_half);
        let iv = Interval { w_e, emf: SQRT_2_3 * w_m, rot, vers, u0: C64::new(0.0, 0.0) };
        (iv, sin_half, cos_half)
    })
}

/// `(sin φ/2, cos φ/2)` of an interval of electrical speed `w_e` \[rad/s\] and length `h`
/// \[s\] (`φ = ω_e h`): [`sin_cos_small`] up to `|φ/2| = π/4` (a quarter of the sample
/// rate, beyond any sensible log), the library's `sin_cos` beyond.
#[inline(always)]
pub(crate) fn half_angle(w_e: f64, h: f64) -> (f64, f64) {
    let x = half_angle_arg(w_e, h);
    if x.abs() <= SMALL_ANGLE { sin_cos_small(x) } else { x.sin_cos() }
}

/// The half angle `φ/2 = ω_e h / 2` \[rad\] of [`half_angle`].
#[inline(always)]
pub(crate) fn half_angle_arg(w_e: f64, h: f64) -> f64 {
    0.5 * (w_e * h)
}

/// Largest |x| for which [`sin_cos_small`] is used: π/4.
pub(crate) const SMALL_ANGLE: f64 = std::f64::consts::FRAC_PI_4;

/// The rotation `e^{−jφ} = (1 − 2 sin²(φ/2), −2 sin(φ/2) cos(φ/2))` and the versine
/// `1 − cos φ = 2 sin²(φ/2)` (free of cancellation near 0) from one sine and cosine of
/// the half angle.
#[inline]
pub(crate) fn half_angle_rotation(sin_half: f64, cos_half: f64) -> (C64, f64) {
    let vers = 2.0 * sin_half * sin_half;
    (C64::new(1.0 - vers, -2.0 * sin_half * cos_half), vers)
}

/// Which voltage drives the model (MODEL.md §4, "Reference versus actual voltage").
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum VoltageInput {
    /// The measured terminal voltage `ud, uq`: the period mean over `[t_k, t_k + h)`.
    #[default]
    Terminal,
    /// The controller's reference `ud_ref, uq_ref` computed at `t_k`, applied `delay`
    /// samples later with a modulator angle advance of `advance · ω_e h` and held in the
    /// stator frame (an inverter). It lacks the inverter's own voltage error.
    Reference {
        /// Computational delay d \[samples\]; 1 for a drive that computes at `t_k` and
        /// applies over `[t_{k+1}, t_{k+2})`.
        delay: usize,
        /// Modulator angle advance in units of `ω_e h` (1.5 compensates the delay and the
        /// half-period mean).
        advance: f64,
        /// Bandwidth α_o \[rad/s\] of the phase-locked loop by which the controller estimates
        /// the speed it advances with, from the logged angle `theta_m`
        /// (`ω̂ += h α_o² e`, `θ̂ += h (ω̂ + 2 α_o e)`, `e = θ_e − θ̂`); `None`: the logged speed.
        #[serde(default)]
        speed_pll: Option<f64>,
    },
}

impl VoltageInput {
    /// The usual drive: reference applied one sample late with a 1.5 ω_e h advance.
    pub const REFERENCE: Self = Self::Reference { delay: 1, advance: 1.5, speed_pll: None };

    /// Samples at the start of a log whose applied voltage precedes the log (the first
    /// `delay` intervals): their step uses the first reference, so a fit weights out the
    /// residuals up to sample `delay`.
    pub fn unknown_start(&self) -> usize {
        match self {
            Self::Terminal => 0,
            Self::Reference { delay, .. } => *delay,
        }
    }
}

impl std::fmt::Display for VoltageInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Terminal => f.write_str("terminal voltage"),
            Self::Reference { delay, advance, speed_pll } => {
                write!(f, "reference voltage, delay {delay} sample(s), advance {advance} ω_e h")?;
                match speed_pll {
                    Some(a) => write!(f, " at the speed of a {a:.1} rad/s phase-locked loop"),
                    None => Ok(()),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The polynomial sine and cosine are the library's to an ulp over `[−π/4, π/4]`, odd
    /// and even, and `half_angle` switches to the library's past π/4.
    #[test]
    fn the_small_angle_sine_and_cosine_are_the_librarys_to_an_ulp() {
        let ulp = |v: f64| f64::EPSILON * v.abs().max(f64::MIN_POSITIVE);
        let mut xs: Vec<f64> = (0..=200_000).map(|k| k as f64 / 200_000.0 * SMALL_ANGLE).collect();
        xs.extend([1e-300, 1e-20, 1e-9, 2f64.powi(-27), 0.1, 0.5, 0.67, SMALL_ANGLE]);
        for x in xs {
            let (s, c) = sin_cos_small(x);
            let (s0, c0) = x.sin_cos();
            assert!((s - s0).abs() <= ulp(s0), "sin {x}: {s} vs {s0}");
            assert!((c - c0).abs() <= ulp(c0), "cos {x}: {c} vs {c0}");
            assert_eq!(sin_cos_small(-x), (-s, c), "odd sine, even cosine at {x}");
        }
        for x in [0.786, 1.0, 3.0, -2.5, 100.0] {
            assert_eq!(half_angle(2.0 * x, 1.0), x.sin_cos(), "past π/4 at {x}");
        }
        assert_eq!(half_angle(2.0 * 0.3, 1.0), sin_cos_small(0.3));
    }

    /// [`stator_hold_start_half`] is [`stator_hold_start`] to a few ulps, the half-angle
    /// rotation is `rotation(φ)` likewise, and near 0 the versine keeps its relative
    /// accuracy.
    #[test]
    fn the_half_angle_forms_are_the_direct_ones() {
        let mean = C64::new(12.5, -230.25);
        let mut phis: Vec<f64> = (-4000..=4000).map(|k| k as f64 * 7.3e-4).collect();
        phis.extend([1e-9, -1e-9, 1e-8, -1e-8, 1.1e-8, 3.0, -3.1, 25.0, 1e-5, -2e-7]);
        let close = |a: f64, b: f64, scale: f64, what: &str, phi: f64| {
            assert!((a - b).abs() <= 8.0 * f64::EPSILON * scale, "{what} at φ = {phi}: {a} vs {b}");
        };
        for phi in phis {
            let (s, c) = (0.5 * phi).sin_cos();
            let got = stator_hold_start_half(mean, phi, s, c);
            let want = stator_hold_start(mean, phi);
            close(got.re, want.re, want.norm(), "u0.re", phi);
            close(got.im, want.im, want.norm(), "u0.im", phi);
            let vers = 2.0 * s * s;
            let direct = rotation(phi);
            close(1.0 - vers, direct.re, 1.0, "cos φ", phi);
            close(-2.0 * s * c, direct.im, 1.0, "−sin φ", phi);
            if phi.abs() < 1e-3 {
                // Near 0 the versine keeps its digits: φ²/2 − φ⁴/24 to 1e-16 relative.
                let series = phi * phi * (0.5 - phi * phi / 24.0);
                close(vers, series, series, "1 − cos φ", phi);
            }
        }
    }
}
