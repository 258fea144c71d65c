//! The steady-state voltage equations of one sample, continuous or at the drive's control
//! period, and their instrumental-variable sums over the steady samples of the logs
//! ([`super::steady`]).
//!
//! Continuous (the period means of a drive at constant speed and currents, MODEL.md §2):
//!
//! ```text
//! u_d = R_s i_d − ω_e L_q i_q
//! u_q = R_s i_q + ω_e L_d i_d + √(2/3) ω_m K_e
//! ```
//!
//! A logger's current is a point sample at the start of a control period, and a voltage
//! held in the stator frame turns backwards in dq by `ω_e h_c` over the period, so the dq
//! current ripples about its period mean even in steady state: at the period's start it is
//! off by `−j ω_e u h_c²/(12 L)` (to first order), which the continuous equations read as a
//! back-EMF lower by `(ω_e h_c)²/12` (−0.1 % at `ω_e h_c` = 0.11). With the control period
//! `h_c` given, the predicted voltage is the exact one: the start voltage `u₀` whose
//! stator-held step leaves the measured current where it was (`i = step(i, u₀)`, the
//! periodic steady state of the offline models' exact step, [`ExactPlant`]), as the dq
//! period mean `ū = u₀ (1 − e^{−jφ})/(jφ)`, `φ = ω_e h_c` (MODEL.md §4).

use crate::error::{Error, Result};
use crate::estimate::iv::IvSums;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::{C64, SQRT_2_3, VoltageHold, stator_hold_start};
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::plant::{ExactPlant, MotorParameters};

/// The steady-state equations of a motor kind with `n_p` pole pairs, a known series
/// resistance, and optionally the drive's control period.
pub(crate) struct SteadyEquations {
    kind: MotorKind,
    n_p: u32,
    cable: f64,
    /// The exact plant at the control period, when it is given.
    plant: Option<ExactPlant>,
    h_c: f64,
}

/// One log's view and the indices of its steady samples.
pub(crate) struct SteadyLog<'a> {
    pub view: DqView<'a>,
    pub steady: Vec<usize>,
    /// The columns of the full parameter vector that model parameter j takes in this log
    /// (length n_θ of the model).
    pub columns: Vec<usize>,
}

impl SteadyEquations {
    /// The equations of `kind`, `n_p` pole pairs, cable resistance `cable` \[Ω\], control
    /// period `h_c` \[s\] (`None`: continuous).
    ///
    /// # Errors
    /// Those of [`ExactPlant::new`] (a control period not positive and finite).
    pub fn new(kind: MotorKind, n_p: u32, cable: f64, h_c: Option<f64>) -> Result<Self> {
        let plant =
            h_c.map(|h| ExactPlant::new(n_p, h, kind == MotorKind::Ipm, VoltageHold::Stator)).transpose()?;
        Ok(Self { kind, n_p, cable, plant, h_c: h_c.unwrap_or(0.0) })
    }

    /// The continuous equations' d and q rows at currents `(i_d, i_q)` \[A\] and mechanical
    /// speed `w_m` \[rad/s\] (model order; `u = row · θ`), with the cable's voltage apart.
    pub fn rows(&self, i_d: f64, i_q: f64, w_m: f64) -> ([f64; 4], [f64; 4]) {
        let w_e = f64::from(self.n_p) * w_m;
        match self.kind {
            MotorKind::Spm => ([i_d, -w_e * i_q, 0.0, 0.0], [i_q, w_e * i_d, SQRT_2_3 * w_m, 0.0]),
            MotorKind::Ipm => ([i_d, 0.0, -w_e * i_q, 0.0], [i_q, w_e * i_d, 0.0, SQRT_2_3 * w_m]),
        }
    }

    /// The predicted dq voltage `[u_d, u_q]` \[V\] at model parameters `theta` (model order,
    /// SI), current `i` \[A\] and speed `w_m` \[rad/s\]: continuous, or the exact periodic
    /// steady state at the control period (module documentation).
    ///
    /// # Errors
    /// Those of [`ExactPlant::step`] (parameters out of range); [`Error::Numerical`] when
    /// the step does not depend on the voltage (a singular input matrix).
    pub fn voltage(&mut self, theta: &[f64], i: [f64; 2], w_m: f64) -> Result<[f64; 2]> {
        let Some(plant) = self.plant.as_mut() else {
            let (rd, rq) = self.rows(i[0], i[1], w_m);
            let dot = |r: &[f64; 4]| r.iter().zip(theta).map(|(a, b)| a * b).sum::<f64>();
            return Ok([dot(&rd) + self.cable * i[0], dot(&rq) + self.cable * i[1]]);
        };
        let (l_d, l_q, k_e) = match self.kind {
            MotorKind::Spm => (theta[1], theta[1], theta[2]),
            MotorKind::Ipm => (theta[1], theta[2], theta[3]),
        };
        let np = f64::from(self.n_p);
        let p = MotorParameters {
            r_s: theta[0] + self.cable,
            l_d,
            l_q,
            psi_f: k_e * SQRT_2_3 / np,
            n_p: self.n_p,
        };
        // step(i, u₀) − i is affine in u₀: its value at 0 and along 1 and j.
        let g0 = plant.step(&p, i, C64::new(0.0, 0.0), w_m)?;
        let g1 = plant.step(&p, i, C64::new(1.0, 0.0), w_m)?;
        let gj = plant.step(&p, i, C64::new(0.0, 1.0), w_m)?;
        let (a, b, c, d) = (g1[0] - g0[0], gj[0] - g0[0], g1[1] - g0[1], gj[1] - g0[1]);
        let det = a * d - b * c;
        let (r0, r1) = (i[0] - g0[0], i[1] - g0[1]);
        let u0 = C64::new((d * r0 - b * r1) / det, (a * r1 - c * r0) / det);
        let mean = u0 / stator_hold_start(C64::new(1.0, 0.0), np * w_m * self.h_c);
        if mean.re.is_finite() && mean.im.is_finite() {
            Ok([mean.re, mean.im])
        } else {
            Err(Error::Numerical {
                context: "steady-state fit".into(),
                reason: format!(
                    "the exact step at the control period does not depend on the voltage at θ = {theta:?}"
                ),
            })
        }
    }

    /// The IV sums at the full parameter vector `theta` over the steady samples of `logs`:
    /// equation error `ū − û(θ; i_k, ω_k)`, Jacobian the continuous rows at sample k (exact
    /// without a control period, within `(ω_e h_c)²` with one: the iteration converges to
    /// the exact equations' root all the same), instruments the rows at the mean of the
    /// neighbouring samples `k ± 1`, whose noise is not sample k's.
    ///
    /// # Errors
    /// Those of [`Self::voltage`]; [`Error::MissingChannel`] for a log without the
    /// terminal voltage.
    pub fn sums(&mut self, logs: &[SteadyLog<'_>], theta: &[f64]) -> Result<IvSums> {
        let n = self.kind.parameter_names().len();
        let nth = theta.len();
        let mut acc = IvSums::new(2, nth);
        let (mut d, mut z) = (vec![0.0; 2 * nth], vec![0.0; 2 * nth]);
        let mut local = vec![0.0; n];
        for log in logs {
            let v = &log.view;
            let (u_d, u_q) = v.terminal_voltage()?;
            let (i_d, i_q, w_m) = (v.i_d(), v.i_q(), v.w_m());
            for (l, &c) in local.iter_mut().zip(&log.columns) {
                *l = theta[c];
            }
            acc.start_experiment();
            for &k in &log.steady {
                let (rd, rq) = self.rows(i_d[k], i_q[k], w_m[k]);
                let mean = |x: &[f64]| 0.5 * (x[k - 1] + x[k + 1]);
                let (zd, zq) = self.rows(mean(i_d), mean(i_q), mean(w_m));
                let u = self.voltage(&local, [i_d[k], i_q[k]], w_m[k])?;
                d.fill(0.0);
                z.fill(0.0);
                for (j, &c) in log.columns.iter().enumerate() {
                    (d[c], d[nth + c]) = (-rd[j], -rq[j]);
                    (z[c], z[nth + c]) = (-zd[j], -zq[j]);
                }
                acc.add(&[u_d[k] - u[0], u_q[k] - u[1]], &d, &z);
            }
            acc.end_experiment();
        }
        Ok(acc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact steady state at the control period against its first-order expansion: the
    /// point-sampled current is off its period mean by `−j ω_e ū h_c²/(12 L)` (SPM).
    #[test]
    fn control_period_correction_matches_first_order() {
        let (r, l, k_e, n_p) = (1.2, 5e-3, 0.49, 4);
        let mut exact = SteadyEquations::new(MotorKind::Spm, n_p, 0.0, Some(1e-4)).unwrap();
        let mut cont = SteadyEquations::new(MotorKind::Spm, n_p, 0.0, None).unwrap();
        let (i, w_m) = ([0.0, 3.0], 280.0);
        let theta = [r, l, k_e];
        let ue = exact.voltage(&theta, i, w_m).unwrap();
        let uc = cont.voltage(&theta, i, w_m).unwrap();
        // First order: ū = Z (i − δ) + jω_eψ with δ = −jω_e ū h²/(12 L), so ū − u_cont = −Z δ.
        let w_e = f64::from(n_p) * w_m;
        let ubar = C64::new(ue[0], ue[1]);
        let delta = C64::new(0.0, -w_e) * ubar * (1e-4f64.powi(2) / (12.0 * l));
        let predicted = -(C64::new(r, w_e * l) * delta);
        let got = C64::new(ue[0] - uc[0], ue[1] - uc[1]);
        assert!((got - predicted).norm() < 0.05 * predicted.norm(), "{got} vs {predicted}");
        // And it is the back-EMF's (ω_e h)²/12 in size.
        assert!((predicted.norm() / (uc[1]) / ((w_e * 1e-4).powi(2) / 12.0) - 1.0).abs() < 0.2);
    }
}
