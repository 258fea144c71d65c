//! Data-side PMSM helpers shared by every PMSM model and available to user models: the
//! voltage hold, interval-mean speed, the rotation `e^{−jω_e h}` of the dq frame over a
//! period and the start-of-period voltage of a stator-held voltage (MODEL.md §4).
//!
//! Over interval k, `[t_k, t_{k+1})`, the speed is taken at its interval mean
//! `ω_m = (ω_m[k] + ω_m[k+1])/2`, so the current equation is linear and time-invariant over
//! the period and has an exact discretisation (thesis 5.2; MODEL.md §4).

use super::signals::DqView;
use crate::error::{Error, Result};
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

/// Interval-mean mechanical speed `(w_m[k] + w_m[k+1])/2` [rad/s] for `k = 0..N−2`,
/// length N − 1 (MODEL.md §4: the speed of the exact step).
pub fn interval_mean_speed(w_m: &[f64]) -> Vec<f64> {
    w_m.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect()
}

/// Rotation of the dq frame over one period, `e^{−jφ}` with `φ = ω_e h` [rad].
pub fn rotation(phi: f64) -> C64 {
    C64::new(phi.cos(), -phi.sin())
}

/// Start-of-period dq voltage `u₀ = ū jφ/(1 − e^{−jφ})` of a stator-held voltage whose
/// dq period mean is `ū` (MODEL.md §4); the limit φ → 0 is `ū`.
pub fn stator_hold_start(mean: C64, phi: f64) -> C64 {
    if phi.abs() < 1e-8 {
        // jφ/(1 − e^{−jφ}) = 1 + jφ/2 − φ²/12 + O(φ⁴)
        return mean * C64::new(1.0 - phi * phi / 12.0, 0.5 * phi);
    }
    let denom = -cexpm1(C64::new(0.0, -phi));
    mean * C64::new(0.0, phi) / denom
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

/// Data-only quantities of one sample interval, shared by the SPM and IPM models.
#[derive(Clone, Copy, Debug)]
pub struct Interval {
    /// Interval-mean electrical speed ω_e [rad/s].
    pub w_e: f64,
    /// `√(2/3)` × interval-mean mechanical speed [rad/s]: back-EMF per unit K_e.
    pub emf: f64,
    /// Rotation of the dq frame over the period, `e^{−jφ}`, `φ = ω_e h`.
    pub rot: C64,
    /// `1 − cos φ`, free of cancellation near 0.
    pub vers: f64,
    /// dq voltage at the start of the period [V]: `u[k]` (dq hold) or `u₀` (stator hold).
    pub u0: C64,
}

/// The intervals `k = 0..N−2` of a log on a machine with `n_p` pole pairs: interval-mean
/// speed, rotation and the start-of-period voltage for the given hold (MODEL.md §4).
pub fn intervals<'a>(v: &DqView<'a>, n_p: u32, hold: VoltageHold) -> impl Iterator<Item = Interval> + 'a {
    let h = v.h();
    let np = f64::from(n_p);
    let (wm, ud, uq) = (v.w_m(), v.u_d(), v.u_q());
    (0..v.len() - 1).map(move |k| {
        let w_m = 0.5 * (wm[k] + wm[k + 1]);
        let w_e = np * w_m;
        let phi = w_e * h;
        let uk = C64::new(ud[k], uq[k]);
        let half = (0.5 * phi).sin();
        Interval {
            w_e,
            emf: SQRT_2_3 * w_m,
            rot: rotation(phi),
            vers: 2.0 * half * half,
            u0: match hold {
                VoltageHold::Dq => uk,
                VoltageHold::Stator => stator_hold_start(uk, phi),
            },
        }
    })
}

/// Checks a pole-pair number.
///
/// # Errors
/// [`Error::InvalidPolePairs`] for `n_p = 0`.
pub(crate) fn check_pole_pairs(n_p: u32) -> Result<()> {
    if n_p == 0 { Err(Error::InvalidPolePairs { n_p }) } else { Ok(()) }
}

/// `e^{w} − 1` for complex w without cancellation near 0.
pub(crate) fn cexpm1(w: C64) -> C64 {
    let (s, c) = w.im.sin_cos();
    let half = (0.5 * w.im).sin();
    C64::new(w.re.exp_m1() * c - 2.0 * half * half, w.re.exp() * s)
}
