//! The surface-magnet PMSM model, `L_d = L_q = L_s`: [`PmsmSpm`] documents it and its exact step.

use crate::pmsm::log::signals::check_pole_pairs;
use crate::pmsm::model::interval::{
    C64, IntervalSource, VoltageHold, check_finite, check_positive, half_angle_rotation,
};
use crate::pmsm::model::inverter::dead_time_directions;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;

const KIND: MotorKind = MotorKind::Spm;
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{BlockKernel, GreyBoxModel, Parameter, Sensitivities};
use crate::pmsm::log::signals::DqView;

mod inverse;
mod kernel;

/// The data of the SPM step, independent of θ: its intervals' source (the experiment's
/// speed and voltage channels, shared, not copied), from which each interval's terms are
/// formed as the pass needs them ([`IntervalSource::interval`]), and the inverter's error
/// directions.
#[derive(Clone, Debug)]
pub struct SpmInputs {
    /// Sample time, pole pairs, speed and voltage of the intervals.
    pub source: IntervalSource,
    /// The inverter's voltage error per unit `v_dt` of each interval, length N − 1, in the
    /// convention of the voltage term (rotated to the period's end for the stator hold);
    /// empty without the inverter model.
    pub dt: Vec<C64>,
}

/// θ-dependent coefficients of the SPM step.
#[derive(Clone, Debug)]
pub struct SpmCoefficients {
    /// Number of parameters n_θ (3, or 4 with `v_dt`).
    nth: usize,
    /// Inverter voltage error `v_dt` \[V\] (0 without the inverter model).
    v_dt: f64,
    r: f64,
    l: f64,
    k_e: f64,
    /// `e^{−R_s h/L_s}`.
    d: f64,
    /// `1 − e^{−R_s h/L_s}` without cancellation.
    one_minus_d: f64,
    /// `(1 − e^{−R_s h/L_s})/R_s` \[1/Ω\].
    g: f64,
    g_r: f64,
    g_l: f64,
    /// `∂a/∂R_s / a = −h/L_s`.
    a_r: f64,
    /// `∂a/∂L_s / a = R_s h/L_s²`.
    a_l: f64,
}

/// Surface-magnet PMSM (`L_d = L_q = L_s`) with the exact zero-order-hold step.
///
/// State and output `x = y = (i_d, i_q)` \[A, peak\]; parameters `θ = (r_s, l_s, k_e)`
/// \[Ω, H, V s/rad\]. Continuous model (thesis eq. 5.1, MODEL.md §2), in complex form with
/// `i = i_d + j i_q`, `ω_e = n_p ω_m`:
///
/// ```text
/// L_s di/dt = u − (R_s + j ω_e L_s) i − j √(2/3) K_e ω_m
/// ```
///
/// Exact step over one period (MODEL.md §4), `z = R_s + j ω_e L_s`, `a = e^{−z h/L_s}`:
///
/// ```text
/// dq hold:      i[k+1] = a i[k] + (1 − a)/z · (u[k] − j e)
/// stator hold:  i[k+1] = a i[k] + u₀ e^{−jφ} (1 − e^{−R_s h/L_s})/R_s − (1 − a)/z · j e
/// ```
///
/// with `e = √(2/3) K_e ω_m`, `φ = ω_e h`, `u₀ = u[k] jφ/(1 − e^{−jφ})`; `ω_m` is the
/// interval mean `(ω_m[k] + ω_m[k+1])/2`. The rotation `e^{−jφ}` and `u₀` depend on the
/// data only; they are formed block by block in the pass from the experiment's own
/// channels, which [`GreyBoxModel::prepare`] shares rather than copies (one sine and cosine
/// of `φ/2` an interval, so that a fit of the terminal voltage keeps nothing per sample
/// beyond the data; a reference input keeps its start-of-period voltages, the inverter
/// model its error directions, 16 bytes an interval each).
/// `e^{−R_s h/L_s}` depends on θ only and is computed once per θ. Sensitivities
/// differentiate this recursion (forward sensitivity), so one pass gives residuals and
/// gradients.
///
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
    /// reported by [`GreyBoxModel::prepare`] as [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError::InvalidPolePairs).
    pub fn new(n_p: u32, hold: VoltageHold) -> Self {
        Self::from_setup(PmsmSetup::new(n_p, hold))
    }

    crate::pmsm::model::setup::pmsm_model_setup!();
}

/// Turns each interval's dq vector by its period's rotation `e^{−jφ}`: a stator-held vector
/// at the start of the period, seen at its end.
fn to_period_end(v: &mut [C64], source: &IntervalSource) {
    for (k, x) in v.iter_mut().enumerate().take(source.intervals()) {
        let (s, c) = source.half_angle(k);
        *x *= half_angle_rotation(s, c).0;
    }
}

impl GreyBoxModel for PmsmSpm {
    type Inputs = SpmInputs;
    type Coefficients = SpmCoefficients;

    crate::pmsm::model::metadata::pmsm_model_metadata!(|_: &Self| KIND);

    fn prepare(&self, e: &Experiment) -> Result<SpmInputs> {
        check_pole_pairs(self.setup.n_p)?;
        let v = DqView::try_new(e)?;
        let source = IntervalSource::of_log(&v, self.setup.n_p, self.setup.hold, self.setup.input)?;
        let mut inputs = SpmInputs { source, dt: Vec::new() };
        if let Some(inv) = &self.setup.inverter {
            let mut dirs = dead_time_directions(&v, self.setup.n_p, inv)?;
            if self.setup.hold == VoltageHold::Stator {
                // Rotated to the end of the period, as the stator-held voltage.
                to_period_end(&mut dirs, &inputs.source);
            }
            inputs.dt = dirs;
        }
        Ok(inputs)
    }

    fn coefficients(&self, theta: &[f64], inputs: &SpmInputs) -> Result<SpmCoefficients> {
        let nth = self.params.len();
        let (r, l, k_e, v_dt) = match *theta {
            [r, l, k_e] if nth == 3 => (r, l, k_e, 0.0),
            [r, l, k_e, v_dt] if nth == 4 => (r, l, k_e, v_dt),
            _ => {
                return Err(Error::InvalidOption {
                    option: "theta".into(),
                    reason: format!("{} values for the {nth} parameters of `{}`", theta.len(), self.name()),
                });
            }
        };
        check_finite("v_dt", v_dt)?;
        let r = self.setup.series_resistance(r)?;
        check_positive("l_s", l)?;
        check_finite("k_e", k_e)?;
        let h = inputs.source.h;
        let x = r * h / l;
        let d = (-x).exp();
        let one_minus_d = -(-x).exp_m1();
        let g = one_minus_d / r;
        Ok(SpmCoefficients {
            nth,
            v_dt,
            r,
            l,
            k_e,
            d,
            one_minus_d,
            g,
            g_r: ((h / l) * d - g) / r,
            g_l: -(h / l) * (d / l),
            a_r: -h / l,
            a_l: r * h / l / l,
        })
    }

    #[inline]
    fn step(&self, c: &SpmCoefficients, inp: &SpmInputs, k: usize, x: &[f64], x_next: &mut [f64]) {
        let t = kernel::terms::<false>(c, inp, self.setup.hold, k);
        let n = t.a * C64::new(x[0], x[1]) + t.forced;
        x_next[0] = n.re;
        x_next[1] = n.im;
    }

    fn block_kernel(&self) -> Option<&dyn BlockKernel<SpmInputs, SpmCoefficients>> {
        Some(self)
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
        let r = kernel::terms::<false>(c, inp, self.setup.hold, k).a * C64::new(v[0], v[1]);
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
        let t = kernel::terms::<true>(c, inp, self.setup.hold, k);
        let ai = t.a * C64::new(x[0], x[1]);
        let n = ai + t.forced;
        x_next[0] = n.re;
        x_next[1] = n.im;
        // Row-major 2 × n_θ: s[j] = ∂i_d/∂θ_j, s[n_θ + j] = ∂i_q/∂θ_j.
        let m = c.nth;
        let col = |j: usize| C64::new(s[j], s[m + j]);
        let mut put = |j: usize, v: C64| {
            s_next[j] = v.re;
            s_next[m + j] = v.im;
        };
        put(0, t.a * col(0) + ai * c.a_r + t.f_r);
        put(1, t.a * col(1) + ai * c.a_l + t.f_l);
        put(2, t.a * col(2) + t.f_k);
        if m == 4 {
            put(3, t.a * col(3) + t.f_v);
        }
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
        let n = dy.len();
        dy.copy_from_slice(&s[..n]);
    }
}
