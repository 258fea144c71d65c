//! The rotor's acceleration inside a period: the resistive drop along the path of the
//! magnets' flux, which a step at the period's mean speed leaves out.
//!
//! The period's step ([`super::period`]) turns the rotor at its mean speed `ω̄`, so its angle
//! is linear in time and ends where the log's does. An accelerating rotor turns on a
//! parabola, `θ(t) = θ₀ + ω₀ t + a_e t²/2`, `a_e` \[rad/s²\] the electrical acceleration:
//! inside the period it lags the linear angle by `δθ(t) = a_e t (t − h)/2` (0 at both ends,
//! `∫₀ʰ δθ dt = −a_e h³/12`). The stator's flux does not feel the angle's path
//! (`dψ_αβ/dt = u_αβ − R i_αβ`), but the current does: at a given stator flux the rotor
//! frame's flux turns, `δψ_dq = −j δθ ψ_dq`, and the current vector `i_αβ = e^{jθ} i_dq`
//! turns with the frame, so in rotor coordinates the current deviates by
//! `δi = j δθ i_dq + L⁻¹ δψ_dq = δθ (i_q (L_q − L_d)/L_d, (i_d (L_q − L_d) − ψ_f)/L_q)`, and
//! its resistive drop integrates into the stator flux what the linear angle's current never
//! drops. At the period's end (`δθ(h) = 0`) that is, to first order in `a_e h²`,
//!
//! ```text
//! δi_d(h) = R a_e (h³/12) i_q (L_q − L_d) / L_d²,
//! δi_q(h) = R (h³/12) (a_e i_d (L_q − L_d) − a_e ψ_f) / L_q²,
//! ```
//!
//! with `a_e ψ_f = K_e √(2/3) a_m` (`a_m` the mechanical acceleration, MODEL.md §1) and the
//! currents at the period's start. Neglected: the frame's rotation and the current's decay
//! inside the period (relative `ω_e h / 2` and `R h / L`, a few per cent of a correction that
//! is itself 1.6e-9 A per rad/s² on the shared servo), and a speed that is not linear
//! inside the period (the sag of [`super::angle_speed`], 50 × smaller in the angle).
//!
//! Measured: on the shared 3 µs log regenerated with every column to 17 digits (the same
//! motulator 0.18 scenario), the one-step residual at the true parameters was
//! `−1.61e-9 A × a_m` in `i_q` (R² 0.94 over 72 000 periods, no dependence on the speed or
//! the current beyond it; regressed on this term, 0.990 ± 0.001 of it); the formula gives
//! `−1.63e-9`, and an exact integration of the accelerating machine over one period agrees
//! with it within 1 % (SPM) and 10 % (IPM, d and q). Left out, it is a q voltage in phase
//! with the torque, and the fit took part of it into `R_s` (+9 ppm on that log, 3.9 of its
//! noise-free standard errors). With it and the angle's mean speed ([`super::angle_speed`]),
//! the regenerated IPM log with its exact angle steps is within |z| 1.0 of the truth.

use super::dual::Scalar;
use super::period::{Params, Period};

impl Period {
    /// The same period on a rotor accelerating at `a_e` \[rad/s², electrical\] and `a_m`
    /// \[rad/s², mechanical\].
    pub(crate) fn accelerating(self, a_e: f64, a_m: f64) -> Self {
        Self { acc_e: a_e, emf_rate: crate::pmsm::model::interval::SQRT_2_3 * a_m, ..self }
    }
}

/// The dq current at the end of period `per` \[A\] from `x`, the step's at its mean speed,
/// with the acceleration's resistive drop added for the start current `x0` \[A\] and
/// parameters `q` (module documentation). `x` itself where the period does not accelerate.
#[inline(always)]
pub(crate) fn with_acceleration<T: Scalar>(q: &Params<T>, per: &Period, x0: [T; 2], x: [T; 2]) -> [T; 2] {
    if per.acc_e == 0.0 && per.emf_rate == 0.0 {
        return x;
    }
    let c = q.r * (per.len().powi(3) / 12.0);
    let saliency = q.l_q - q.l_d;
    if saliency.is_zero() {
        // A surface-magnet machine: the magnets' term alone (the same numbers).
        return [x[0], x[1] + c * -(q.k_e * per.emf_rate) / (q.l_q * q.l_q)];
    }
    let d = c * per.acc_e * saliency * x0[1] / (q.l_d * q.l_d);
    let e = c * (saliency * x0[0] * per.acc_e - q.k_e * per.emf_rate) / (q.l_q * q.l_q);
    [x[0] + d, x[1] + e]
}

/// The correction's derivatives with respect to the start current, row-major
/// `[∂δi_d/∂i_d, ∂δi_d/∂i_q, ∂δi_q/∂i_d, ∂δi_q/∂i_q]` \[1\] (for the period's transition).
pub(crate) fn transition_terms<T: Scalar>(q: &Params<T>, per: &Period) -> [T; 4] {
    let zero = T::cst(0.0);
    if per.acc_e == 0.0 {
        return [zero; 4];
    }
    let c = q.r * (per.len().powi(3) / 12.0 * per.acc_e) * (q.l_q - q.l_d);
    [zero, c / (q.l_d * q.l_d), c / (q.l_q * q.l_q), zero]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pmsm::model::pwm::period;

    /// The correction is the module's formula, and 0 without acceleration; the period's
    /// transition holds its derivative with respect to the start (finite differences).
    #[test]
    fn the_acceleration_drops_the_magnets_flux_path_through_r() {
        let per = period::tests::test_period();
        let q = Params { r: 0.9, l_d: 4.5e-3, l_q: 6.0e-3, k_e: 0.54, t_d: 2e-6, u_th: 0.8, i_w: None };
        let x0 = [-1.0, 5.0];
        let x = period::step(&q, &per, x0);
        let (a_m, n_p) = (1200.0, 4.0);
        let acc = per.accelerating(n_p * a_m, a_m);
        let y = period::step(&q, &acc, x0);
        let h = per.len();
        let c = 0.9 * h.powi(3) / 12.0;
        let want_d = c * n_p * a_m * (q.l_q - q.l_d) * x0[1] / (q.l_d * q.l_d);
        let want_q = c
            * (n_p * a_m * (q.l_q - q.l_d) * x0[0] - 0.54 * crate::pmsm::model::interval::SQRT_2_3 * a_m)
            / (q.l_q * q.l_q);
        assert!(((y[0] - x[0]) - want_d).abs() < 1e-15, "{} {want_d}", y[0] - x[0]);
        assert!(((y[1] - x[1]) - want_q).abs() < 1e-15, "{} {want_q}", y[1] - x[1]);
        assert!(want_q < -1e-7, "a correction of {want_q} A is too small to test");
        let phi = period::transition(&q, &acc);
        for j in 0..2 {
            let mut up = x0;
            up[j] += 1e-3;
            let mut down = x0;
            down[j] -= 1e-3;
            let (a, b) = (period::step(&q, &acc, up), period::step(&q, &acc, down));
            for i in 0..2 {
                let fd = (a[i] - b[i]) / 2e-3;
                assert!((phi[2 * i + j] - fd).abs() < 1e-9, "Φ[{i}][{j}] {} against {fd}", phi[2 * i + j]);
            }
        }
    }
}
