//! The SPM step solved for its voltage: the inverse model of the instrumental-variable
//! method (`crate::pmsm::fit::iv`).
//!
//! The exact step of interval k (module docs of [`super`]; MODEL.md §4) is affine in the
//! current and in the voltage term `u` (`u[k]` for the dq hold, `u₀ e^{−jφ}` for the stator
//! hold): `i[k+1] = a i[k] + B u + c` with `B = (1 − a)/z` (dq hold) or
//! `(1 − e^{−R_s h/L_s})/R_s` (stator hold) and `c = −(1 − a)/z · j e`, `e = √(2/3) K_e ω_m`.
//! Hence the voltage term the currents imply, `û = (i[k+1] − a i[k] − c)/B`, exact for any
//! θ, and its derivatives `∂û/∂θ = −(∂a/∂θ i[k] + ∂c/∂θ + û ∂B/∂θ)/B`.

use super::kernel::{Core, core};
use super::{PmsmSpm, SpmCoefficients, SpmInputs};
use crate::pmsm::model::interval::{C64, VoltageHold};

/// The θ- and data-dependent terms of interval k's step for its inversion, with their
/// derivatives by `(r_s, l_s, k_e)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct InverseStep {
    /// The measured voltage term `u` of the interval \[V\].
    pub u: C64,
    a: C64,
    gain: C64,
    c: C64,
    da: [C64; 3],
    dgain: [C64; 3],
    dc: [C64; 3],
}

/// `b · j e`.
fn times_j(b: C64, e: f64) -> C64 {
    C64::new(-b.im * e, b.re * e)
}

impl InverseStep {
    /// The voltage term `û` \[V\] the currents `i0 = i[k]`, `i1 = i[k+1]` \[A\] imply, and its
    /// derivatives by `(r_s, l_s, k_e)` \[V/Ω, V/H, rad/s\].
    pub(crate) fn voltage(&self, i0: C64, i1: C64) -> (C64, [C64; 3]) {
        let u = (i1 - self.a * i0 - self.c) / self.gain;
        let d = std::array::from_fn(|j| -(self.da[j] * i0 + self.dc[j] + u * self.dgain[j]) / self.gain);
        (u, d)
    }
}

impl PmsmSpm {
    /// The inversion terms of interval k (`k < N − 1`) at the coefficients `c` of a
    /// three-parameter model (no inverter model).
    ///
    /// # Panics
    /// If k ≥ N − 1.
    pub(crate) fn inverse_step(&self, c: &SpmCoefficients, inp: &SpmInputs, k: usize) -> InverseStep {
        let hold = self.setup.hold;
        let (half, w_m, u) = inp.source.interval(hold, k);
        let Core { w, emf, a, z_inv, b, e } = core(c, inp.source.n_p, half, w_m);
        let b_r = (a * (-c.a_r) - b) * z_inv;
        let b_l = (a * (-c.a_l) - times_j(b, w)) * z_inv;
        let zero = C64::default();
        let (gain, dgain) = match hold {
            VoltageHold::Stator => (C64::new(c.g, 0.0), [C64::new(c.g_r, 0.0), C64::new(c.g_l, 0.0), zero]),
            VoltageHold::Dq => (b, [b_r, b_l, zero]),
        };
        InverseStep {
            u,
            a,
            gain,
            c: -times_j(b, e),
            da: [a * c.a_r, a * c.a_l, zero],
            dgain,
            dc: [-times_j(b_r, e), -times_j(b_l, e), -times_j(b, emf)],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::GreyBoxModel;
    use crate::pmsm::log::signals::DqSignals;

    /// The inverse gives back the voltage term the step was driven by, and its derivatives
    /// agree with central differences, for both holds.
    #[test]
    fn inverse_undoes_the_step() {
        let n = 20;
        let f = |a: f64, b: f64, c: f64| (0..n).map(|k| a + b * (c * k as f64).sin()).collect::<Vec<f64>>();
        let s = DqSignals {
            u_d: f(1.0, 4.0, 0.7),
            u_q: f(25.0, 6.0, 0.3),
            i_d: vec![0.0; n],
            i_q: vec![0.0; n],
            w_m: f(150.0, 60.0, 0.2),
            theta_m: None,
            u_d_ref: None,
            u_q_ref: None,
        };
        let e = s.into_experiment("t", 1e-4).unwrap();
        let theta = [0.9, 4.5e-3, 0.539];
        for hold in [VoltageHold::Stator, VoltageHold::Dq] {
            let m = PmsmSpm::new(4, hold);
            let inp = m.prepare(&e).unwrap();
            let c = m.coefficients(&theta, &inp).unwrap();
            let i0 = C64::new(1.5, -2.0);
            let mut next = [0.0; 2];
            for k in 0..n - 1 {
                m.step(&c, &inp, k, &[i0.re, i0.im], &mut next);
                let inv = m.inverse_step(&c, &inp, k);
                let (u, d) = inv.voltage(i0, C64::new(next[0], next[1]));
                assert!((u - inv.u).norm() < 1e-9 * inv.u.norm(), "{hold}: k {k}: {u} vs {}", inv.u);
                for (j, dj) in d.iter().enumerate() {
                    let at = |f: f64| {
                        let mut t = theta;
                        t[j] *= f;
                        let c = m.coefficients(&t, &inp).unwrap();
                        m.inverse_step(&c, &inp, k).voltage(i0, C64::new(next[0], next[1])).0
                    };
                    let fd = (at(1.0 + 1e-6) - at(1.0 - 1e-6)) / (2e-6 * theta[j]);
                    assert!((fd - dj).norm() <= 1e-5 * dj.norm().max(1.0), "{hold}: ∂û/∂θ_{j}: {dj} vs {fd}");
                }
            }
        }
    }
}
