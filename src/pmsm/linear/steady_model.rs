//! The steady-state voltage equations of one sample, continuous or at the drive's control
//! period, and their instrumental-variable sums over the steady samples of the logs
//! ([`super::steady`]).
//!
//! Continuous (the period means of a drive at slowly varying speed and currents, MODEL.md
//! §2), with the currents' drift `di/dt` at the log's rate (central differences of the
//! point samples, `(i[k+1] − i[k−1])/(2h)`: the short plateaus and ramps of a real drive
//! cycle are not constant):
//!
//! ```text
//! u_d = R_s i_d + L_d di_d/dt − ω_e L_q i_q
//! u_q = R_s i_q + L_q di_q/dt + ω_e L_d i_d + √(2/3) ω_m K_e
//! ```
//!
//! A logger's current is a point sample at the start of a control period, and a voltage
//! held in the stator frame turns backwards in dq by `ω_e h_c` over the period, so the dq
//! current ripples about its period mean even in steady state: at the period's start it is
//! off by `−j ω_e ū h_c²/(12 L)` (to first order), which the continuous equations read as a
//! back-EMF lower by `(ω_e h_c)²/12` (−0.1 % at `ω_e h_c` = 0.11). Two ways to model it:
//!
//! - `h_c` given: the exact step of the stator-held voltage: the start voltage `u₀` whose
//!   step carries the measured current on by its drift over the period
//!   (`step(i, u₀) = i + h_c di/dt`, [`ExactPlant`]), as the dq period mean
//!   `ū = u₀ (1 − e^{−jφ})/(jφ)`, `φ = ω_e h_c` (MODEL.md §4).
//! - `h_c` unknown (the default): its first-order effect as a nuisance parameter
//!   `h_c2 = h_c²` of the regression. With `c = h_c²/12` and `ī = i + (h_c/2) di/dt −
//!   ω_e c (ū_q/L_d, −ū_d/L_q)` the period-mean current (the point sample is the period's
//!   start: a drifting current's mean lies half its drift over the period on),
//!   `ū = Z ī + L di/dt + jω_e ψ` gives the columns `−c ω_e² ū` and the small terms
//!   `−(R_s/L_d) ω_e c ū_q` (d), `+(R_s/L_q) ω_e c ū_d` (q), the drift's `(h_c/2) Z di/dt`,
//!   and the speed's period mean `ω̄ = ω_k + (h_c/2) dω/dt` in every speed term; the small
//!   terms are evaluated at the current estimate and the instrumental-variable step
//!   iterated (a gym-electric-motor log, whose dq voltage is held in dq, gives `h_c2 ≈ 0`).
//!   The drift's term is first order in `h_c = √h_c2`, whose slope at 0 has no bound: it
//!   is left out until the iteration has converged, then held at the period found there
//!   where `h_c2`'s 95 % interval lies above 0 ([`SteadyEquations::drift`]), and the
//!   iteration goes on (a log whose voltage is no period mean, `h_c2 ≤ 0`, keeps the
//!   continuous equations: with the term free, a noise-free 100 Hz log of curving currents
//!   took L_s 13 % off).
//!   Without the drift's term the fit reads `L_q` about `(h_c/2) ⟨(di_q/dt)/i_q⟩` high:
//!   +1.6e-4 … +2.0e-4 on every 20th–80th row of an independent 5 kHz log of moves under
//!   a sinusoidal load, at `|z|` up to 2.1 (the full-rate log's steady-state fit: −5e-5).

use crate::error::{Error, Result};
use crate::estimate::iv::IvSums;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::{C64, SQRT_2_3, VoltageHold, stator_hold_start};
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::plant::{ExactPlant, MotorParameters};

/// Most model parameters: IPM `r_s, l_d, l_q, k_e` and the period term.
const MAX_COLUMNS: usize = 5;

/// One steady sample: the point-sampled currents and speed, their drift at the log's rate
/// and the logged (period-mean) voltage.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sample {
    /// `[i_d, i_q]` \[A\].
    pub i: [f64; 2],
    /// `[di_d/dt, di_q/dt]` \[A/s\].
    pub di: [f64; 2],
    /// Mechanical speed \[rad/s\].
    pub w_m: f64,
    /// Its derivative \[rad/s²\].
    pub dw: f64,
    /// `[u_d, u_q]` \[V\].
    pub u: [f64; 2],
}

impl Sample {
    /// Sample k of `view` (sample time `h` \[s\]) as the regressors read it: values at k,
    /// derivatives by central differences over `k ± a`.
    fn regressor(view: &DqView<'_>, u: (&[f64], &[f64]), k: usize, a: usize, h: f64) -> Self {
        Self::with_level(view, u, k, a, h, |x| x[k])
    }

    /// Sample k of `view` as the instruments read it: the means and central differences of
    /// `k ± a` (`a` one more than the regressors', so that their noise is not that of the
    /// samples the equation error holds).
    fn instrument(view: &DqView<'_>, u: (&[f64], &[f64]), k: usize, a: usize, h: f64) -> Self {
        Self::with_level(view, u, k, a, h, |x| 0.5 * (x[k + a] + x[k - a]))
    }

    /// Sample k with the values `level` of each signal and its central difference over `k ± a`.
    fn with_level(
        view: &DqView<'_>,
        u: (&[f64], &[f64]),
        k: usize,
        a: usize,
        h: f64,
        level: impl Fn(&[f64]) -> f64,
    ) -> Self {
        let (i_d, i_q, w_m) = (view.i_d(), view.i_q(), view.w_m());
        let slope = |x: &[f64]| (x[k + a] - x[k - a]) / (2.0 * a as f64 * h);
        Self {
            i: [level(i_d), level(i_q)],
            di: [slope(i_d), slope(i_q)],
            w_m: level(w_m),
            dw: slope(w_m),
            u: [level(u.0), level(u.1)],
        }
    }
}

/// The steady-state equations of a motor kind with `n_p` pole pairs, a known series
/// resistance, and the drive's control period given or estimated.
pub(crate) struct SteadyEquations {
    kind: MotorKind,
    n_p: u32,
    cable: f64,
    /// The exact plant at the control period, when it is given.
    plant: Option<ExactPlant>,
    h_c: f64,
    /// Whether the continuous equations estimate the period term.
    estimate: bool,
    /// Half width of the regressors' central differences, in samples
    /// ([`super::SteadyOptions::derivative_half_width`]).
    half_width: usize,
    /// The control period \[s\] whose drifting currents' period mean the continuous
    /// equations take (0: none), held while `h_c2` is estimated ([`Self::drift`]).
    drift: f64,
}

/// One log's view, its sample time and the indices of its steady samples.
pub(crate) struct SteadyLog<'a> {
    pub view: DqView<'a>,
    /// Sample time \[s\].
    pub h: f64,
    /// Steady samples k (each with samples `k ± (a + 1)` in the log, `a` the derivatives'
    /// half width).
    pub steady: Vec<usize>,
    /// The columns of the full parameter vector that model parameter j takes in this log
    /// (length n_θ of the model).
    pub columns: Vec<usize>,
}

impl SteadyEquations {
    /// The equations of `kind`, `n_p` pole pairs, cable resistance `cable` \[Ω\], control
    /// period `h_c` \[s\] (`None`: continuous, with the nuisance `h_c2` when `estimate`).
    ///
    /// # Errors
    /// Those of [`ExactPlant::new`] (a control period not positive and finite).
    pub fn new(kind: MotorKind, n_p: u32, cable: f64, h_c: Option<f64>, estimate: bool) -> Result<Self> {
        let plant =
            h_c.map(|h| ExactPlant::new(n_p, h, kind == MotorKind::Ipm, VoltageHold::Stator)).transpose()?;
        Ok(Self { kind, n_p, cable, plant, h_c: h_c.unwrap_or(0.0), estimate, half_width: 1, drift: 0.0 })
    }

    /// The equations with the currents' and the speed's central differences over `k ± a`
    /// (`a ≥ 1`; 1 by default), the instruments' over `k ± (a + 1)`: the samples need those
    /// in the log.
    pub fn half_width(self, a: usize) -> Self {
        Self { half_width: a.max(1), ..self }
    }

    /// The continuous equations with the drifting currents' period mean `i + (h_c/2) di/dt`
    /// at the control period `h_c` \[s\] in their resistance and speed terms (module
    /// documentation): held, not estimated, because the term is first order in
    /// `h_c = √h_c2`; the exact equations (a given control period) have it already.
    pub fn drift(self, h_c: f64) -> Self {
        Self { drift: h_c, ..self }
    }

    /// Whether the period term `h_c2` is a parameter (continuous equations that estimate it).
    pub fn estimates_period(&self) -> bool {
        self.plant.is_none() && self.estimate
    }

    /// Model parameters: the kind's, then `h_c2` when it is estimated.
    pub fn n_columns(&self) -> usize {
        self.kind.parameter_names().len() + usize::from(self.estimates_period())
    }

    /// The d and q rows at sample `s` (model order, SI; `u = row · θ` up to the small
    /// terms), with the cable's voltage apart.
    pub fn rows(&self, s: &Sample) -> ([f64; MAX_COLUMNS], [f64; MAX_COLUMNS]) {
        let w_e = f64::from(self.n_p) * s.w_m;
        let [i_d, i_q] = s.i;
        let [di_d, di_q] = s.di;
        let (mut rd, mut rq) = match self.kind {
            MotorKind::Spm => {
                ([i_d, di_d - w_e * i_q, 0.0, 0.0, 0.0], [i_q, di_q + w_e * i_d, SQRT_2_3 * s.w_m, 0.0, 0.0])
            }
            MotorKind::Ipm => {
                ([i_d, di_d, -w_e * i_q, 0.0, 0.0], [i_q, w_e * i_d, di_q, SQRT_2_3 * s.w_m, 0.0])
            }
        };
        if self.estimates_period() {
            let c = self.kind.parameter_names().len();
            (rd[c], rq[c]) = (-w_e * w_e * s.u[0] / 12.0, -w_e * w_e * s.u[1] / 12.0);
        }
        (rd, rq)
    }

    /// `(R_s + cable, L_d, L_q, K_e)` of model parameters `theta`.
    fn motor(&self, theta: &[f64]) -> (f64, f64, f64, f64) {
        match self.kind {
            MotorKind::Spm => (theta[0] + self.cable, theta[1], theta[1], theta[2]),
            MotorKind::Ipm => (theta[0] + self.cable, theta[1], theta[2], theta[3]),
        }
    }

    /// The predicted dq voltage `[u_d, u_q]` \[V\] at model parameters `theta` (model order,
    /// SI) and sample `s` (module documentation).
    ///
    /// # Errors
    /// Those of [`ExactPlant::step`] (parameters out of range); [`Error::Numerical`] when
    /// the step does not depend on the voltage (a singular input matrix).
    pub fn voltage(&mut self, theta: &[f64], s: &Sample) -> Result<[f64; 2]> {
        let (r, l_d, l_q, k_e) = self.motor(theta);
        let np = f64::from(self.n_p);
        let Some(plant) = self.plant.as_mut() else {
            let (rd, rq) = self.rows(s);
            let dot = |row: &[f64; MAX_COLUMNS]| row.iter().zip(theta).map(|(a, b)| a * b).sum::<f64>();
            // The small terms at the current estimate: the ripple's rotation and the
            // period means of the speed and of the drifting currents.
            let c = match self.estimates_period() {
                true => theta[self.kind.parameter_names().len()].max(0.0) / 12.0,
                false => 0.0,
            };
            let (mut d, mut q) = (dot(&rd) + self.cable * s.i[0], dot(&rq) + self.cable * s.i[1]);
            let w_e = np * s.w_m;
            if c > 0.0 {
                let dw = 0.5 * (12.0 * c).sqrt() * s.dw;
                d += -r / l_d * w_e * c * s.u[1] - np * dw * l_q * s.i[1];
                q += r / l_q * w_e * c * s.u[0] + np * dw * l_d * s.i[0] + SQRT_2_3 * k_e * dw;
            }
            if self.drift > 0.0 {
                let [di_d, di_q] = s.di.map(|x| 0.5 * self.drift * x);
                d += r * di_d - w_e * l_q * di_q;
                q += r * di_q + w_e * l_d * di_d;
            }
            return Ok([d, q]);
        };
        let w_m = s.w_m + 0.5 * self.h_c * s.dw;
        let p = MotorParameters { r_s: r, l_d, l_q, psi_f: k_e * SQRT_2_3 / np, n_p: self.n_p };
        let i = s.i;
        // step(i, u₀) − i is affine in u₀: its value at 0 and along 1 and j.
        let g0 = plant.step(&p, i, C64::new(0.0, 0.0), w_m)?;
        let g1 = plant.step(&p, i, C64::new(1.0, 0.0), w_m)?;
        let gj = plant.step(&p, i, C64::new(0.0, 1.0), w_m)?;
        let (a, b, c, d) = (g1[0] - g0[0], gj[0] - g0[0], g1[1] - g0[1], gj[1] - g0[1]);
        let det = a * d - b * c;
        // The step that carries the current on by its drift over the period, h_c di/dt.
        let (r0, r1) = (i[0] + self.h_c * s.di[0] - g0[0], i[1] + self.h_c * s.di[1] - g0[1]);
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
    /// equation error `ū − û(θ; sample k)`, Jacobian the rows at sample k (without the
    /// small terms, and without a control period's exact correction: the iteration
    /// converges to the equations' root all the same), instruments the rows at the means
    /// and slopes over `k ± (a + 1)` (`a` the derivatives' half width, [`Self::half_width`]),
    /// whose noise is not that of the samples the equation error holds. The score is kept in
    /// blocks of `block` samples, so that a short log still gives the batch means of a
    /// coloured equation error.
    ///
    /// # Errors
    /// Those of [`Self::voltage`]; [`Error::MissingChannel`] for a log without the
    /// terminal voltage.
    pub fn sums(&mut self, logs: &[SteadyLog<'_>], theta: &[f64], block: usize) -> Result<IvSums> {
        let nth = theta.len();
        let mut acc = IvSums::with_block_len(2, nth, block);
        let (mut d, mut z) = (vec![0.0; 2 * nth], vec![0.0; 2 * nth]);
        let mut local = vec![0.0; self.n_columns()];
        for log in logs {
            let v = &log.view;
            let u = v.terminal_voltage()?;
            for (l, &c) in local.iter_mut().zip(&log.columns) {
                *l = theta[c];
            }
            acc.start_experiment();
            let a = self.half_width;
            for &k in &log.steady {
                let sample = Sample::regressor(v, u, k, a, log.h);
                let (rd, rq) = self.rows(&sample);
                let (zd, zq) = self.rows(&Sample::instrument(v, u, k, a + 1, log.h));
                let p = self.voltage(&local, &sample)?;
                d.fill(0.0);
                z.fill(0.0);
                for (j, &c) in log.columns.iter().enumerate() {
                    (d[c], d[nth + c]) = (-rd[j], -rq[j]);
                    (z[c], z[nth + c]) = (-zd[j], -zq[j]);
                }
                acc.add(&[sample.u[0] - p[0], sample.u[1] - p[1]], &d, &z);
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
        let mut exact = SteadyEquations::new(MotorKind::Spm, n_p, 0.0, Some(1e-4), false).unwrap();
        let mut cont = SteadyEquations::new(MotorKind::Spm, n_p, 0.0, None, true).unwrap();
        assert_eq!(cont.n_columns(), 4);
        let (i, w_m) = ([0.0, 3.0], 280.0);
        let theta = [r, l, k_e];
        let at = |u: [f64; 2]| Sample { i, di: [0.0; 2], w_m, dw: 0.0, u };
        let ue = exact.voltage(&theta, &at([0.0; 2])).unwrap();
        let uc = cont.voltage(&[r, l, k_e, 0.0], &at(ue)).unwrap();
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

    /// The estimated period term reproduces the exact periodic steady state to first order:
    /// with `h_c2 = h_c²` the continuous equations' prediction at the exact voltage lands on
    /// it far closer than without.
    #[test]
    fn period_term_matches_the_exact_steady_state() {
        let (r, l, k_e, n_p, h_c) = (1.2, 5e-3, 0.49, 4, 1e-4);
        let mut exact = SteadyEquations::new(MotorKind::Spm, n_p, 0.0, Some(h_c), false).unwrap();
        let mut cont = SteadyEquations::new(MotorKind::Spm, n_p, 0.0, None, true).unwrap();
        for (i, w_m) in [([0.0, 3.0], 280.0), ([2.0, -4.0], -150.0), ([-1.0, 6.0], 60.0)] {
            let at = |u: [f64; 2]| Sample { i, di: [0.0; 2], w_m, dw: 0.0, u };
            let ue = exact.voltage(&[r, l, k_e], &at([0.0; 2])).unwrap();
            let with = cont.voltage(&[r, l, k_e, h_c * h_c], &at(ue)).unwrap();
            let without = cont.voltage(&[r, l, k_e, 0.0], &at(ue)).unwrap();
            let err = |p: [f64; 2]| (p[0] - ue[0]).hypot(p[1] - ue[1]);
            assert!(err(with) < 0.02 * err(without), "{} vs {} at {w_m}", err(with), err(without));
        }
    }

    /// A drifting current: the exact equations' voltage is the period mean of the
    /// stator-held voltage whose exact step carries the current on by `h_c di/dt`, and the
    /// continuous equations with the period term land on it far within the drift's own
    /// period-mean term `(h_c/2) Z di/dt` (which equations reading the current at the
    /// period's start miss).
    #[test]
    fn a_drifting_current_is_read_at_its_period_mean() {
        let (r, l_d, l_q, k_e, n_p, h_c) = (0.5, 4.2e-3, 8e-3, 0.4, 4, 2e-4);
        let theta = [r, l_d, l_q, k_e];
        let mut exact = SteadyEquations::new(MotorKind::Ipm, n_p, 0.0, Some(h_c), false).unwrap();
        let mut cont = SteadyEquations::new(MotorKind::Ipm, n_p, 0.0, None, true).unwrap().drift(h_c);
        let mut plant = ExactPlant::new(n_p, h_c, true, VoltageHold::Stator).unwrap();
        let p = MotorParameters { r_s: r, l_d, l_q, psi_f: k_e * SQRT_2_3 / f64::from(n_p), n_p };
        for (i, di, w_m) in [([0.0, 3.0], [0.0, 400.0], 180.0), ([-5.0, 6.0], [-300.0, -500.0], -120.0)] {
            let s = Sample { i, di, w_m, dw: 0.0, u: [0.0; 2] };
            let ue = exact.voltage(&theta, &s).unwrap();
            let w_e = f64::from(n_p) * w_m;
            let u0 = C64::new(ue[0], ue[1]) * stator_hold_start(C64::new(1.0, 0.0), w_e * h_c);
            let next = plant.step(&p, i, u0, w_m).unwrap();
            for a in 0..2 {
                assert!((next[a] - i[a] - h_c * di[a]).abs() < 1e-9, "{next:?} from {i:?} by {di:?}");
            }
            let uc = cont.voltage(&[r, l_d, l_q, k_e, h_c * h_c], &Sample { u: ue, ..s }).unwrap();
            let drift = 0.5 * h_c * (r * di[0] - w_e * l_q * di[1]).hypot(r * di[1] + w_e * l_d * di[0]);
            let err = (uc[0] - ue[0]).hypot(uc[1] - ue[1]);
            assert!(err < 0.05 * drift, "{err} against the drift's {drift} at {w_m}");
        }
    }
}
