//! The surface-magnet PMSM model, `L_d = L_q = L_s`: [`PmsmSpm`] documents it and its exact step.

use crate::pmsm::log::signals::check_pole_pairs;
use crate::pmsm::model::interval::{
    C64, IntervalSource, VoltageHold, check_finite, check_positive, half_angle_rotation,
};
use crate::pmsm::model::inverter::dead_time_directions;

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{BlockKernel, GreyBoxModel, Sensitivities};
use crate::pmsm::log::signals::DqView;

mod inverse;
mod kernel;
mod types;

use types::KIND;
pub use types::{PmsmSpm, SpmCoefficients, SpmInputs};

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
