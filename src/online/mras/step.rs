//! The observer's exact one-period steps and their sensitivities (see the parent module's
//! documentation): the closed-form surface-magnet step and the salient step through
//! [`ExactPlant`], with the `(1 − e^{−w})/w` functions they use.

use super::super::config::Adaptation;
use super::state::{Mras, Sample};
use crate::error::{Error, Result};
use crate::pmsm::{
    C64, ExactPlant, MotorParameters, SQRT_2_3, VoltageHold, cexpm1, rotation, stator_hold_start,
};

impl Mras {
    /// The exact one-period step of the observer's model (surface or salient) from the
    /// state `x` \[A\] at `(k_e, r_s)`: the next current, its sensitivities to `K_e` and
    /// `R_s`, and the step's transition matrix `∂i[k+1]/∂i[k]`, `(i[k+1], ∂i[k+1]/∂K_e,
    /// ∂i[k+1]/∂R_s, Φ)` (dq currents complex, `d + j q`; Φ row-major, `[[∂d/∂d, ∂d/∂q],
    /// [∂q/∂d, ∂q/∂q]]`): of the surface-magnet step in closed form (the rotation and decay
    /// `a`), of the salient one by the step's linearity in the current (two more steps).
    ///
    /// # Errors
    /// [`Error::Numerical`] when the salient step fails (naming the sample).
    pub(crate) fn model_step_transition(
        &self,
        x: C64,
        k_e: f64,
        r_s: f64,
        s: &Sample,
    ) -> Result<(C64, C64, C64, [[f64; 2]; 2])> {
        match &self.plant {
            None => {
                let ((next, phi_k, phi_r, _), a) = self.step(x, k_e, r_s, s);
                Ok((next, phi_k, phi_r, [[a.re, -a.im], [a.im, a.re]]))
            }
            Some(plant) => {
                let (next, phi_k, phi_r, _) = self.step_salient(plant, x, k_e, r_s, s)?;
                let (d, ..) = self.step_salient(plant, x + C64::new(1.0, 0.0), k_e, r_s, s)?;
                let (q, ..) = self.step_salient(plant, x + C64::new(0.0, 1.0), k_e, r_s, s)?;
                let (d, q) = (d - next, q - next);
                Ok((next, phi_k, phi_r, [[d.re, q.re], [d.im, q.im]]))
            }
        }
    }

    /// The exact SPM step from the corrected state `x` at `(k_e, r_s)`: the next
    /// prediction and its sensitivities `(î, φ_K, φ_R, ψ_K)`, and the step's factor `a` of
    /// the current (`î = a x + …`).
    pub(super) fn step(&self, x: C64, k_e: f64, r_s: f64, s: &Sample) -> ((C64, C64, C64, C64), C64) {
        let (l, h) = (self.cfg.l_s, self.cfg.h);
        let hl = h / l;
        let w_e = f64::from(self.cfg.n_p) * s.w_m;
        let rot = rotation(w_e * h);
        let d = (-r_s * hl).exp();
        let a = rot * d;
        let w = C64::new(r_s, w_e * l) * hl;
        let b = phi1(w) * hl;
        let b_r = phi1_prime(w) * (hl * hl);
        let je = C64::new(0.0, SQRT_2_3 * s.w_m * k_e);
        let u = C64::new(s.u_d, s.u_q);
        let (forced, forced_r) = match self.cfg.hold {
            VoltageHold::Dq => (b * (u - je), b_r * (u - je)),
            VoltageHold::Stator => {
                // u₀ e^{−jφ} (1 − e^{−R h/L})/R, the exact stator-hold term (MODEL.md §4).
                let u_s = stator_hold_start(u, w_e * h) * rot;
                let xr = C64::new(r_s * hl, 0.0);
                (u_s * (phi1(xr).re * hl) - b * je, u_s * (phi1_prime(xr).re * hl * hl) - b_r * je)
            }
        };
        let i_next = a * x + forced;
        let phi_k = -b * C64::new(0.0, SQRT_2_3 * s.w_m);
        let psi_k = match self.cfg.adaptation {
            Adaptation::Lyapunov | Adaptation::Normalised => phi_k,
            Adaptation::Relay => -b * C64::new(0.0, SQRT_2_3 * if s.w_m < 0.0 { -1.0 } else { 1.0 }),
        };
        let phi_r = a * (-hl) * x + forced_r;
        ((i_next, phi_k, phi_r, psi_k), a)
    }
}

impl Mras {
    /// The exact salient step from the corrected state `x` at `(k_e, r_s)` and its exact
    /// sensitivities, `(î, φ_K, φ_R, ψ_K)` as [`Mras::step`] (module documentation).
    pub(super) fn step_salient(
        &self,
        plant: &ExactPlant,
        x: C64,
        k_e: f64,
        r_s: f64,
        s: &Sample,
    ) -> Result<(C64, C64, C64, C64)> {
        let n_p = self.cfg.n_p;
        let p = MotorParameters {
            r_s,
            l_d: self.cfg.l_s,
            l_q: self.cfg.l_q.unwrap_or(self.cfg.l_s),
            psi_f: SQRT_2_3 * k_e / f64::from(n_p),
            n_p,
        };
        let u = C64::new(s.u_d, s.u_q);
        let u0 = match self.cfg.hold {
            VoltageHold::Dq => u,
            VoltageHold::Stator => stator_hold_start(u, f64::from(n_p) * s.w_m * self.cfg.h),
        };
        let d = plant.step_derivatives(&p, [x.re, x.im], u0, s.w_m).map_err(|e| Error::Numerical {
            context: format!("MRAS update at sample {}", self.n),
            reason: e.to_string(),
        })?;
        let c = |v: [f64; 2]| C64::new(v[0], v[1]);
        let phi_k = c(d.d_k_e);
        let psi_k = match self.cfg.adaptation {
            Adaptation::Lyapunov | Adaptation::Normalised => phi_k,
            // φ_K is proportional to ω_m (its direction depends on ω_m only through the
            // rotation within the period): φ_K/|ω_m|, and 0 at standstill where K_e has
            // no effect on the step.
            Adaptation::Relay if s.w_m != 0.0 => phi_k / s.w_m.abs(),
            Adaptation::Relay => C64::default(),
        };
        Ok((c(d.next), phi_k, c(d.d_r_s), psi_k))
    }
}

/// `(1 − e^{−w})/w`, with its limit 1 at w = 0 and no cancellation near it.
fn phi1(w: C64) -> C64 {
    if w.norm() < 1e-3 {
        // 1 − w/2 + w²/6 − w³/24 + w⁴/120, error below |w|⁵/720.
        return C64::new(1.0, 0.0) + w * (-0.5 + w * (1.0 / 6.0 + w * (-1.0 / 24.0 + w / 120.0)));
    }
    -cexpm1(-w) / w
}

/// `d/dw (1 − e^{−w})/w = ((1 + w) e^{−w} − 1)/w²`, limit −1/2 at w = 0.
fn phi1_prime(w: C64) -> C64 {
    if w.norm() < 1e-2 {
        // −1/2 + w/3 − w²/8 + w³/30 − w⁴/144 + w⁵/840, error below |w|⁶/5760.
        return C64::new(-0.5, 0.0)
            + w * (1.0 / 3.0 + w * (-1.0 / 8.0 + w * (1.0 / 30.0 + w * (-1.0 / 144.0 + w / 840.0))));
    }
    (cexpm1(-w) * (w + 1.0) + w) / (w * w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_meet_closed_forms_at_their_switch() {
        for w in
            [C64::new(1.1e-3, 0.2e-3), C64::new(0.0, 9e-4), C64::new(0.011, -0.003), C64::new(0.0, 0.0099)]
        {
            // The series of φ₁ holds below |w| = 1e-3, with error |w|⁵/720.
            let closed = -cexpm1(-w) / w;
            let series = C64::new(1.0, 0.0) + w * (-0.5 + w * (1.0 / 6.0 + w * (-1.0 / 24.0 + w / 120.0)));
            assert!((closed - series).norm() < 1e-14 + w.norm().powi(5) / 720.0 * 1.01, "{w}");
            let closed_p = (cexpm1(-w) * (w + 1.0) + w) / (w * w);
            let series_p = C64::new(-0.5, 0.0)
                + w * (1.0 / 3.0 + w * (-1.0 / 8.0 + w * (1.0 / 30.0 + w * (-1.0 / 144.0 + w / 840.0))));
            assert!((closed_p - series_p).norm() < 1e-11, "{w}");
            let d = 1e-5;
            let fd = (phi1(w + d) - phi1(w - d)) / (2.0 * d);
            assert!((phi1_prime(w) - fd).norm() < 1e-8, "{w}");
        }
    }
}
