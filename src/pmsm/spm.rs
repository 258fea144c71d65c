//! Surface-magnet PMSM (`L_d = L_q = L_s`) with the exact zero-order-hold step.
//!
//! State and output `x = y = (i_d, i_q)` [A, peak]; parameters `θ = (r_s, l_s, k_e)`
//! [Ω, H, V s/rad]. Continuous model (thesis eq. 5.1, MODEL.md §2), in complex form with
//! `i = i_d + j i_q`, `ω_e = n_p ω_m`:
//!
//! ```text
//! L_s di/dt = u − (R_s + j ω_e L_s) i − j √(2/3) K_e ω_m
//! ```
//!
//! Exact step over one period (MODEL.md §4), `z = R_s + j ω_e L_s`, `a = e^{−z h/L_s}`:
//!
//! ```text
//! dq hold:      i[k+1] = a i[k] + (1 − a)/z · (u[k] − j e)
//! stator hold:  i[k+1] = a i[k] + u₀ e^{−jφ} (1 − e^{−R_s h/L_s})/R_s − (1 − a)/z · j e
//! ```
//!
//! with `e = √(2/3) K_e ω_m`, `φ = ω_e h`, `u₀ = u[k] jφ/(1 − e^{−jφ})`; `ω_m` is the
//! interval mean `(ω_m[k] + ω_m[k+1])/2`. The rotation `e^{−jφ}` and `u₀` depend on the
//! data only and are computed once in [`GreyBoxModel::prepare`]; `e^{−R_s h/L_s}` depends on
//! θ only and is computed once per θ. Sensitivities differentiate this recursion
//! (forward sensitivity), so one pass gives residuals and gradients.

use super::interval::{C64, VoltageHold, VoltageInput, check_pole_pairs, check_positive, model_intervals};
use super::kind::MotorKind;
use super::setup::PmsmSetup;

const KIND: MotorKind = MotorKind::Spm;
use super::signals::DqView;
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Parameter, Sensitivities};

/// Per-interval data of the SPM step, independent of θ (index k = 0..N−2).
#[derive(Clone, Debug)]
pub struct SpmInputs {
    /// Sample time h [s].
    pub h: f64,
    /// Interval-mean electrical speed ω_e [rad/s].
    pub w_e: Vec<f64>,
    /// `√(2/3)` × interval-mean mechanical speed [rad/s]: back-EMF per unit K_e.
    pub emf: Vec<f64>,
    /// Rotation of the dq frame over the period, `e^{−j ω_e h}`.
    pub rot: Vec<C64>,
    /// Versine of the period's rotation, `1 − cos(ω_e h) = 2 sin²(ω_e h/2)` (exact near 0).
    pub vers: Vec<f64>,
    /// Voltage term of the step [V]: `u[k]` (dq hold) or `u₀ e^{−jφ}` (stator hold).
    pub u: Vec<C64>,
}

/// θ-dependent coefficients of the SPM step.
#[derive(Clone, Debug)]
pub struct SpmCoefficients {
    r: f64,
    l: f64,
    k_e: f64,
    h: f64,
    /// `e^{−R_s h/L_s}`.
    d: f64,
    /// `1 − e^{−R_s h/L_s}` without cancellation.
    one_minus_d: f64,
    /// `(1 − e^{−R_s h/L_s})/R_s` [1/Ω].
    g: f64,
    g_r: f64,
    g_l: f64,
}

/// Surface-magnet PMSM model with exact sampled-data step and analytic sensitivities.
///
/// Parameters `(r_s [Ω], l_s [H], k_e [V s/rad])`; `r_s` and `l_s` bounded positive,
/// `k_e` unbounded (a negative estimate means the log's sign convention differs).
/// Source: thesis eq. 5.1 and section 5.2 (Tenerz 2011); MODEL.md §2, §4.
#[derive(Clone, Debug)]
pub struct PmsmSpm {
    setup: PmsmSetup,
    params: Vec<Parameter>,
}

impl PmsmSpm {
    /// SPM model of a machine with `n_p` pole pairs (`ω_e = n_p ω_m`), the given voltage
    /// hold and default parameter metadata, driven by the terminal voltage. `n_p = 0` is
    /// reported by [`GreyBoxModel::prepare`] as [`Error::InvalidPolePairs`].
    pub fn new(n_p: u32, hold: VoltageHold) -> Self {
        Self { setup: PmsmSetup::new(n_p, hold), params: KIND.parameters() }
    }

    super::setup::pmsm_model_setup!();
}

/// Per-interval speed, rotation and held voltage term of the SPM step.
fn interval_inputs(v: &DqView<'_>, n_p: u32, hold: VoltageHold, input: VoltageInput) -> Result<SpmInputs> {
    let n = v.len() - 1;
    let (mut w_e, mut emf, mut rot, mut vers, mut u) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    for iv in model_intervals(v, n_p, hold, input)? {
        w_e.push(iv.w_e);
        emf.push(iv.emf);
        rot.push(iv.rot);
        vers.push(iv.vers);
        // The stator-held voltage enters the SPM step rotated to the end of the period.
        u.push(match hold {
            VoltageHold::Dq => iv.u0,
            VoltageHold::Stator => iv.u0 * iv.rot,
        });
    }
    Ok(SpmInputs { h: v.h(), w_e, emf, rot, vers, u })
}

impl GreyBoxModel for PmsmSpm {
    type Inputs = SpmInputs;
    type Coefficients = SpmCoefficients;

    super::pmsm_model_metadata!(KIND);

    fn prepare(&self, e: &Experiment) -> Result<SpmInputs> {
        check_pole_pairs(self.setup.n_p)?;
        interval_inputs(&DqView::try_new(e)?, self.setup.n_p, self.setup.hold, self.setup.input)
    }

    fn coefficients(&self, theta: &[f64], inputs: &SpmInputs) -> Result<SpmCoefficients> {
        let &[r, l, k_e] = theta else {
            return Err(Error::InvalidOption {
                option: "theta".into(),
                reason: format!("{} values for the 3 parameters r_s, l_s, k_e", theta.len()),
            });
        };
        check_positive("r_s", r)?;
        let r = r + self.setup.cable_resistance;
        if !(self.setup.cable_resistance.is_finite() && self.setup.cable_resistance >= 0.0) {
            return Err(Error::InvalidParameter {
                name: "cable_resistance".into(),
                value: self.setup.cable_resistance,
                reason: "must be finite and not negative".into(),
            });
        }
        check_positive("l_s", l)?;
        if !k_e.is_finite() {
            return Err(Error::InvalidParameter {
                name: "k_e".into(),
                value: k_e,
                reason: "must be finite".into(),
            });
        }
        let h = inputs.h;
        let x = r * h / l;
        let d = (-x).exp();
        let one_minus_d = -(-x).exp_m1();
        let g = one_minus_d / r;
        Ok(SpmCoefficients {
            r,
            l,
            k_e,
            h,
            d,
            one_minus_d,
            g,
            g_r: ((h / l) * d - g) / r,
            g_l: -(h / l) * (d / l),
        })
    }

    #[inline]
    fn step(&self, c: &SpmCoefficients, inp: &SpmInputs, k: usize, x: &[f64], x_next: &mut [f64]) {
        let (a, b) = self.ab(c, inp, k);
        let i = C64::new(x[0], x[1]);
        let je = C64::new(0.0, c.k_e * inp.emf[k]);
        let forced = match self.setup.hold {
            VoltageHold::Dq => b * (inp.u[k] - je),
            VoltageHold::Stator => inp.u[k] * c.g - b * je,
        };
        let n = a * i + forced;
        x_next[0] = n.re;
        x_next[1] = n.im;
    }

    fn sensitivities(&self) -> Option<&dyn Sensitivities<SpmInputs, SpmCoefficients>> {
        Some(self)
    }

    #[inline]
    fn step_state_derivative(
        &self,
        c: &SpmCoefficients,
        inp: &SpmInputs,
        k: usize,
        _x: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        // The step is affine in i: ∂i[k+1]/∂i[k] · v = a v.
        let (a, _) = self.ab(c, inp, k);
        let r = a * C64::new(v[0], v[1]);
        out[0] = r.re;
        out[1] = r.im;
    }

    #[inline]
    fn output_state_derivative(
        &self,
        _c: &SpmCoefficients,
        _inp: &SpmInputs,
        _k: usize,
        _x: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        out.copy_from_slice(&v[..2]);
    }
}

impl Sensitivities<SpmInputs, SpmCoefficients> for PmsmSpm {
    #[inline]
    fn step_sensitivity(
        &self,
        c: &SpmCoefficients,
        inp: &SpmInputs,
        k: usize,
        x: &[f64],
        s: &[f64],
        x_next: &mut [f64],
        s_next: &mut [f64],
    ) {
        let (a, b) = self.ab(c, inp, k);
        let w = inp.w_e[k];
        let z = C64::new(c.r, w * c.l);
        let hl = c.h / c.l;
        let a_r = a * (-hl);
        let a_l = a * (c.r * hl / c.l);
        let b_r = (a * hl - b) / z;
        let b_l = (a * (-c.r * hl / c.l) - b * C64::new(0.0, w)) / z;
        let i = C64::new(x[0], x[1]);
        let emf = inp.emf[k];
        let je = C64::new(0.0, c.k_e * emf);
        let u = inp.u[k];
        let (forced, f_r, f_l) = match self.setup.hold {
            VoltageHold::Dq => (b * (u - je), b_r * (u - je), b_l * (u - je)),
            VoltageHold::Stator => (u * c.g - b * je, u * c.g_r - b_r * je, u * c.g_l - b_l * je),
        };
        let f_k = -b * C64::new(0.0, emf);
        let n = a * i + forced;
        x_next[0] = n.re;
        x_next[1] = n.im;
        let sr = a * C64::new(s[0], s[3]) + a_r * i + f_r;
        let sl = a * C64::new(s[1], s[4]) + a_l * i + f_l;
        let sk = a * C64::new(s[2], s[5]) + f_k;
        s_next[0] = sr.re;
        s_next[1] = sl.re;
        s_next[2] = sk.re;
        s_next[3] = sr.im;
        s_next[4] = sl.im;
        s_next[5] = sk.im;
    }

    #[inline]
    fn output_sensitivity(
        &self,
        _c: &SpmCoefficients,
        _inp: &SpmInputs,
        _k: usize,
        _x: &[f64],
        s: &[f64],
        dy: &mut [f64],
    ) {
        dy.copy_from_slice(&s[..6]);
    }
}

impl PmsmSpm {
    /// `a = e^{−z h/L}` and `b = (1 − a)/z` for interval k.
    #[inline(always)]
    fn ab(&self, c: &SpmCoefficients, inp: &SpmInputs, k: usize) -> (C64, C64) {
        let w = inp.w_e[k];
        let a = inp.rot[k] * c.d;
        let z = C64::new(c.r, w * c.l);
        // 1 − a = (1 − d) cos φ + (1 − cos φ) + j d sin φ, free of cancellation.
        let rot = inp.rot[k];
        let one_minus_a = C64::new(c.one_minus_d * rot.re + inp.vers[k], -c.d * rot.im);
        (a, one_minus_a / z)
    }
}
