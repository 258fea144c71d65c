//! The measured current's noise on the start of [`PmsmPwm`]'s one-step predictor: the
//! residuals with each period's transition, and the criterion's share of that noise
//! (`crate::pmsm::fit` compensates the criterion for it).

use super::model::{PmsmPwm, PwmInputs};
use crate::error::Result;
use crate::model::GreyBoxModel;
use crate::pmsm::model::pwm::dual::{Dual, Scalar};
use crate::pmsm::model::pwm::period::{self, Params, Period};

impl PmsmPwm {
    /// Per period k of a prepared log at `theta`: the one-step residual of sample k + 1,
    /// `r = y[k+1] − f(x̂[k] + k_o (y[k] − x̂[k]))` \[A\], and `Φ = ∂f/∂y[k]` (2×2, row-major;
    /// forward-mode), how the measured current's noise at sample k enters that residual.
    ///
    /// # Errors
    /// Those of [`coefficients`](GreyBoxModel::coefficients).
    pub(crate) fn noise_terms(&self, theta: &[f64], inputs: &PwmInputs) -> Result<Vec<([f64; 2], [f64; 4])>> {
        let c = self.coefficients(theta, inputs)?;
        let q: Params<Dual> = self.params(theta, |v, _| Dual::cst(v));
        let mut out = Vec::with_capacity(inputs.periods.len());
        let mut x = [inputs.i_d[0], inputs.i_q[0]];
        for (k, per) in inputs.periods.iter().enumerate() {
            let y = [inputs.i_d[k], inputs.i_q[k]];
            let from = self.start_of(c.k_o, x, y);
            let next = period::step(&q, per, [Dual::seed(from[0], 0), Dual::seed(from[1], 1)]);
            x = [next[0].v, next[1].v];
            let r = [inputs.i_d[k + 1] - x[0], inputs.i_q[k + 1] - x[1]];
            let phi = [next[0].d[0], next[0].d[1], next[1].d[0], next[1].d[1]].map(|v| v * c.k_o);
            out.push((r, phi));
        }
        Ok(out)
    }

    /// The share of the one-step criterion that noise `sigma` (2×2 covariance of the
    /// measured dq current \[A²\], row-major) on the predictor's start carries at `theta`:
    /// `c(θ) = ½ Σ_k w[k+1] tr(Λ Φ_k Σ Φ_kᵀ)` with `Φ_k` the period's transition
    /// ([`period::transition`] for hard leg states; for smooth ones, whose voltages depend on
    /// the start, the step's own Jacobian at the measured start, [`smooth_transition`];
    /// `k_o = 1`), `w` the sample weights (length
    /// N), `Λ = diag(lambda)`; and its gradient over θ (length n_θ, exact by forward mode).
    ///
    /// # Errors
    /// Those of [`coefficients`](GreyBoxModel::coefficients).
    pub(crate) fn start_noise_share(
        &self,
        theta: &[f64],
        inputs: &PwmInputs,
        sigma: [f64; 4],
        lambda: [f64; 2],
        w: &[f64],
    ) -> Result<(f64, Vec<f64>)> {
        let c = self.coefficients(theta, inputs)?;
        let total = share(&self.params(&c.theta, Dual::seed), inputs, sigma, lambda, w);
        Ok((total.v, total.d[..c.nth].to_vec()))
    }

    /// [`start_noise_share`](Self::start_noise_share)'s value alone, the same number to the
    /// bit, without the gradient's dual numbers (a trial point's cost).
    ///
    /// # Errors
    /// Those of [`coefficients`](GreyBoxModel::coefficients).
    pub(crate) fn start_noise_share_value(
        &self,
        theta: &[f64],
        inputs: &PwmInputs,
        sigma: [f64; 4],
        lambda: [f64; 2],
        w: &[f64],
    ) -> Result<f64> {
        let c = self.coefficients(theta, inputs)?;
        Ok(share(&c.q, inputs, sigma, lambda, w))
    }
}

/// `½ Σ_k w[k+1] tr(Λ Φ_k Σ Φ_kᵀ)` in the scalar of `q` ([`PmsmPwm::start_noise_share`]).
fn share<T: Scalar>(q: &Params<T>, inputs: &PwmInputs, sigma: [f64; 4], lambda: [f64; 2], w: &[f64]) -> T {
    let mut total = T::cst(0.0);
    for (k, per) in inputs.periods.iter().enumerate() {
        let wk = w.get(k + 1).copied().unwrap_or(0.0);
        if wk <= 0.0 {
            continue;
        }
        let p = match q.i_w {
            None => period::transition(q, per),
            Some(i_w) => smooth_transition(q, per, [inputs.i_d[k], inputs.i_q[k]], i_w.val()),
        };
        // Row i of Φ Σ Φᵀ's diagonal: Φ_i· Σ Φ_i·ᵀ.
        let quad = |a: T, b: T| a * a * sigma[0] + a * b * (sigma[1] + sigma[2]) + b * b * sigma[3];
        total = total + (quad(p[0], p[1]) * lambda[0] + quad(p[2], p[3]) * lambda[1]) * (0.5 * wk);
    }
    total
}

/// The period's transition `Φ = ∂x(h)/∂x(0)` (row-major) at the start `y` \[A\] of a step
/// whose leg states are smooth (width `i_w` \[A\]), with the parameters' derivatives of
/// `q`: central differences over ±10⁻³ `i_w` of the start, each an exact step in dual
/// numbers, so `Φ`'s derivatives over θ are those differences' (relative error about
/// 10⁻⁶, the leg state smooth over `i_w`).
fn smooth_transition<T: Scalar>(q: &Params<T>, per: &Period, y: [f64; 2], i_w: f64) -> [T; 4] {
    let h = 1e-3 * i_w;
    let at = |dx: [f64; 2]| period::step(q, per, [T::cst(y[0] + dx[0]), T::cst(y[1] + dx[1])]);
    let (dp, dm, qp, qm) = (at([h, 0.0]), at([-h, 0.0]), at([0.0, h]), at([0.0, -h]));
    let s = 0.5 / h;
    [(dp[0] - dm[0]) * s, (qp[0] - qm[0]) * s, (dp[1] - dm[1]) * s, (qp[1] - qm[1]) * s]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The smooth legs' transition by central differences is the step's Jacobian over its
    /// start by forward mode (to 1e-7), and it is not the hard legs' `e^{A h}` near a zero
    /// crossing (the start's current moves the blanked legs' voltages).
    #[test]
    fn the_smooth_transition_is_the_steps_jacobian() {
        let per = period::tests::test_period();
        let q =
            Params { r: 0.35, l_d: 3.2e-3, l_q: 7.5e-3, k_e: 0.42, t_d: 3e-6, u_th: 1.2, i_w: Some(0.05) };
        let y = [0.04, -0.03];
        let fd: [f64; 4] = smooth_transition(&q, &per, y, 0.05);
        let next = period::step(&q.constants(), &per, [Dual::seed(y[0], 0), Dual::seed(y[1], 1)]);
        let forward = [next[0].d[0], next[0].d[1], next[1].d[0], next[1].d[1]];
        let hard = period::transition(&q, &per);
        for ((a, b), e) in fd.iter().zip(forward).zip(hard) {
            assert!((a - b).abs() < 1e-7, "{fd:?} against {forward:?}");
            assert!((a - e).abs() > 1e-3, "{fd:?} against e^(Ah) {hard:?}");
        }
    }
}
