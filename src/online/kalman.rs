//! The extended Kalman filter of `R_s` and `K_e` with their covariance (issue 46): an
//! online estimate with an interval at every sample, beside the thesis' MRAS.
//!
//! # Model
//!
//! The state is the dq current and the two parameters, `x = (i_d, i_q, R_s, K_e)`. The
//! current follows the exact one-period step of the machine (MODEL.md §4, the MRAS's own
//! step: surface magnets in closed form, a salient machine by its augmented exponential),
//! the parameters a random walk:
//!
//! ```text
//! i[k+1] = Φ(R_s) i[k] + Γ(R_s, K_e) u[k] + w_i,   w_i ~ N(0, q_i² I)
//! R_s[k+1] = R_s[k] + w_R,                      w_R ~ N(0, q_R² h)
//! K_e[k+1] = K_e[k] + w_K,                      w_K ~ N(0, q_K² h)
//! y[k] = i[k] + v[k],                            v ~ N(0, σ_i² I)
//! ```
//!
//! The filter is the textbook EKF (Simon, *Optimal State Estimation*, 2006, §13.2; for the
//! joint state and parameter form, Ljung, *IEEE Trans. Autom. Control* 24(1), 1979): the
//! prediction linearised by the step's exact sensitivities (`∂i[k+1]/∂R_s`,
//! `∂i[k+1]/∂K_e`, as the MRAS uses them, and `Φ` by the step's linearity in the current),
//! the update in Joseph form (Simon §5.1), so that the covariance stays symmetric and
//! positive. Because the filtered current, not the measured one, enters the step, current
//! noise does not bias the estimates the way it biases an equation-error regression
//! (errors in variables). `R_s` is projected onto `R_s ≥ 0`.
//!
//! The random walks are what lets the estimates follow a winding heating up or a magnet
//! weakening; their intensities `q_R`, `q_K` set how fast, and widen the intervals when
//! nothing changes (conservative, not overconfident). `σ_i` comes from a fit's residuals or
//! from the log itself ([`current_noise`]).

use super::config::MrasConfig;
use super::mras::{Estimates, Mras, Sample, estimates};
use crate::error::{Error, Result};
use crate::pmsm::C64;
use nalgebra::{Matrix2, Matrix4, Matrix4x2, Vector2, Vector4};
use serde::{Deserialize, Serialize};

/// The filter's noise model (see the module doc); all standard deviations.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct KalmanNoise {
    /// `σ_i`: of each measured current, `i_d` and `i_q` \[A\].
    pub sigma_i: f64,
    /// `q_i`: of the current's model error per sample \[A\].
    pub q_i: f64,
    /// `q_R`: random-walk intensity of `R_s` \[Ω/√s\] (its std after one second); with
    /// `relative`, a fraction of the present `R̂_s` \[1/√s\].
    pub q_r_s: f64,
    /// `q_K`: random-walk intensity of `K_e` \[V s/rad/√s\]; with `relative`, a fraction of
    /// the present `|K̂_e|` \[1/√s\].
    pub q_k_e: f64,
    /// Of the initial `R_s` \[Ω\].
    pub p0_r_s: f64,
    /// Of the initial `K_e` \[V s/rad\].
    pub p0_k_e: f64,
    /// The walks in proportion to the present estimates (a winding's resistance and a
    /// magnet's flux change in proportion to themselves, `R_s(T) = R_s0 (1 + α ΔT)`), each
    /// estimate taken at least a hundredth of its initial standard deviation, so that a
    /// filter started without values still moves.
    #[serde(default)]
    pub relative: bool,
}

/// `q_i / σ_i` of [`KalmanNoise::for_machine`].
pub const MODEL_NOISE_RATIO: f64 = 0.05;
/// `q_R / R_s0` of [`KalmanNoise::for_machine`] \[1/√s\]: 2 % of `R_s` per √s.
pub const R_S_WALK: f64 = 0.02;
/// `q_K / K_e0` of [`KalmanNoise::for_machine`] \[1/√s\]: 0.2 % of `K_e` per √s.
pub const K_E_WALK: f64 = 0.002;

impl KalmanNoise {
    /// The default noise model of a machine started at `r_s0` \[Ω\], `k_e0` \[V s/rad\],
    /// with current noise `sigma_i` \[A\]: `q_i = 0.05 σ_i` ([`MODEL_NOISE_RATIO`]), walks
    /// relative to the present estimates, `q_R = 0.02 R̂_s/√s` ([`R_S_WALK`]) and
    /// `q_K = 0.002 |K̂_e|/√s` ([`K_E_WALK`]), initial standard deviations half of `R_s0`
    /// and a fifth of `K_e0` (a start without a value, 0, counts as 1 Ω and 0.1 V s/rad).
    pub fn for_machine(sigma_i: f64, r_s0: f64, k_e0: f64) -> Self {
        let r = if r_s0 > 0.0 { r_s0 } else { 1.0 };
        let k = if k_e0 != 0.0 { k_e0.abs() } else { 0.1 };
        Self {
            sigma_i,
            q_i: MODEL_NOISE_RATIO * sigma_i,
            q_r_s: R_S_WALK,
            q_k_e: K_E_WALK,
            p0_r_s: 0.5 * r,
            p0_k_e: 0.2 * k,
            relative: true,
        }
    }

    /// The walks' intensities `(q_R \[Ω/√s\], q_K \[V s/rad/√s\])` at the estimates
    /// `r_s` \[Ω\], `k_e` \[V s/rad\]: the fields themselves, or with `relative` those
    /// fractions of the estimates (floored, see `relative`).
    pub fn walks_at(&self, r_s: f64, k_e: f64) -> (f64, f64) {
        if !self.relative {
            return (self.q_r_s, self.q_k_e);
        }
        (self.q_r_s * r_s.abs().max(0.01 * self.p0_r_s), self.q_k_e * k_e.abs().max(0.01 * self.p0_k_e))
    }

    /// # Errors
    /// [`Error::InvalidOption`] naming the field: `sigma_i`, `p0_r_s`, `p0_k_e` not
    /// positive and finite; `q_i`, `q_r_s`, `q_k_e` negative or not finite.
    pub fn validate(&self) -> Result<()> {
        let bad = |option: &str, v: f64, what: &str| {
            Err(Error::InvalidOption { option: option.into(), reason: format!("must be {what}, got {v}") })
        };
        for (name, v) in [("sigma_i", self.sigma_i), ("p0_r_s", self.p0_r_s), ("p0_k_e", self.p0_k_e)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, v, "positive and finite");
            }
        }
        for (name, v) in [("q_i", self.q_i), ("q_r_s", self.q_r_s), ("q_k_e", self.q_k_e)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, v, "finite and at least 0");
            }
        }
        Ok(())
    }
}

/// One sample's estimates with their standard errors.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct KalmanEstimate {
    /// The estimates (`e_d`, `e_q`: the innovation, measured minus predicted current \[A\]).
    pub estimates: Estimates,
    /// Standard error of `K_e` \[V s/rad\] (`K_t`, `ψ_f` scale with it).
    pub k_e_se: f64,
    /// Standard error of `R_s` \[Ω\].
    pub r_s_se: f64,
}

/// The extended Kalman filter (module doc), one sample at a time, without allocation.
#[derive(Clone, Debug)]
pub struct Kalman {
    model: Mras,
    noise: KalmanNoise,
    /// The state predicted for the next sample, `(i_d, i_q, R_s, K_e)`.
    x: Vector4<f64>,
    /// Its covariance.
    p: Matrix4<f64>,
    n: usize,
}

impl Kalman {
    /// A filter of the machine of `config` (`n_p`, `l_s`, `l_q`, `h`, `hold`, the initial
    /// `k_e0`, `r_s0`; the MRAS's gains are not used) with the noise model `noise`.
    ///
    /// # Errors
    /// Those of [`MrasConfig::validate`] and [`KalmanNoise::validate`].
    pub fn try_new(config: MrasConfig, noise: KalmanNoise) -> Result<Self> {
        noise.validate()?;
        let model = Mras::try_new(MrasConfig { adaptation: super::Adaptation::Lyapunov, ..config })?;
        Ok(Self { model, noise, x: Vector4::zeros(), p: Matrix4::zeros(), n: 0 })
    }

    /// The machine's settings.
    pub fn config(&self) -> &MrasConfig {
        self.model.config()
    }

    /// Takes sample `s` (the current `i[k]` measured, the voltage `u[k]` and the mean speed
    /// over the period to `i[k+1]`): updates the estimates with `i[k]`, then predicts
    /// `i[k+1]`. The first sample starts the filter at the measured current and the
    /// configured `k_e0`, `r_s0`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite sample (naming the channel and the sample);
    /// [`Error::Numerical`] when the step or the update fails (naming the sample).
    pub fn update(&mut self, s: &Sample) -> Result<KalmanEstimate> {
        for (column, value) in [("id", s.i_d), ("iq", s.i_q), ("ud", s.u_d), ("uq", s.u_q), ("w_m", s.w_m)] {
            if !value.is_finite() {
                return Err(Error::NonFinite { column: column.into(), row: self.n, value });
            }
        }
        let sample = self.n;
        let numerical = move |reason: String| Error::Numerical {
            context: format!("Kalman filter at sample {sample}"),
            reason,
        };
        let y = Vector2::new(s.i_d, s.i_q);
        let s2 = self.noise.sigma_i.powi(2);
        // Worked on copies, committed at the end: a failed update leaves the filter as it was.
        let (mut x, mut p) = (self.x, self.p);
        let innovation = if self.n == 0 {
            let cfg = self.model.config();
            x = Vector4::new(s.i_d, s.i_q, cfg.r_s0, cfg.k_e0);
            p = Matrix4::from_diagonal(&Vector4::new(
                s2,
                s2,
                self.noise.p0_r_s.powi(2),
                self.noise.p0_k_e.powi(2),
            ));
            Vector2::zeros()
        } else {
            let nu = y - x.fixed_rows::<2>(0);
            let s_mat = p.fixed_view::<2, 2>(0, 0) + Matrix2::identity() * s2;
            let inv =
                s_mat.try_inverse().ok_or_else(|| numerical("innovation covariance singular".into()))?;
            let gain: Matrix4x2<f64> = p.fixed_columns::<2>(0) * inv;
            x += gain * nu;
            let mut ikh = Matrix4::identity();
            let mut head = ikh.fixed_columns_mut::<2>(0);
            head -= &gain;
            p = ikh * p * ikh.transpose() + gain * gain.transpose() * s2;
            nu
        };
        x[2] = x[2].max(0.0);
        let (r_s, k_e) = (x[2], x[3]);
        let n_p = self.model.config().n_p;
        let out = KalmanEstimate {
            estimates: estimates(k_e, r_s, n_p, C64::new(innovation[0], innovation[1]), true),
            k_e_se: p[(3, 3)].max(0.0).sqrt(),
            r_s_se: p[(2, 2)].max(0.0).sqrt(),
        };
        let (x, p) = self.predict(x, p, s).map_err(|e| numerical(e.to_string()))?;
        if !(x.iter().all(|v| v.is_finite()) && p.iter().all(|v| v.is_finite())) {
            return Err(numerical(format!("state or covariance not finite (k_e = {k_e}, r_s = {r_s})")));
        }
        (self.x, self.p) = (x, p);
        self.n += 1;
        Ok(out)
    }

    /// The prediction of `(x, P)` to the next sample: `x ← f(x)`, `P ← F P Fᵀ + Q`.
    fn predict(
        &self,
        x: Vector4<f64>,
        mut p: Matrix4<f64>,
        s: &Sample,
    ) -> Result<(Vector4<f64>, Matrix4<f64>)> {
        let (i, r_s, k_e) = (C64::new(x[0], x[1]), x[2], x[3]);
        let (next, phi_k, phi_r, a) = self.model.model_step_transition(i, k_e, r_s, s)?;
        // F = [[Φ, B], [0, I]] with B = [∂i/∂R_s, ∂i/∂K_e]: F P Fᵀ by 2 × 2 blocks,
        // P = [[P_ii, P_ip], [P_ipᵀ, P_pp]]: M = Φ P_ii + B P_ipᵀ, N = Φ P_ip + B P_pp,
        // then [[M Φᵀ + N Bᵀ, N], [Nᵀ, P_pp]].
        let phi = Matrix2::new(a[0][0], a[0][1], a[1][0], a[1][1]);
        let b = Matrix2::new(phi_r.re, phi_k.re, phi_r.im, phi_k.im);
        let p_ii: Matrix2<f64> = p.fixed_view::<2, 2>(0, 0).into_owned();
        let p_ip: Matrix2<f64> = p.fixed_view::<2, 2>(0, 2).into_owned();
        let p_pp: Matrix2<f64> = p.fixed_view::<2, 2>(2, 2).into_owned();
        let m = phi * p_ii + b * p_ip.transpose();
        let n = phi * p_ip + b * p_pp;
        let mut top = m * phi.transpose() + n * b.transpose();
        top = (top + top.transpose()) * 0.5;
        let h = self.model.config().h;
        let q_i = self.noise.q_i.powi(2);
        top[(0, 0)] += q_i;
        top[(1, 1)] += q_i;
        let mut pp = (p_pp + p_pp.transpose()) * 0.5;
        let (q_r, q_k) = self.noise.walks_at(r_s, k_e);
        pp[(0, 0)] += q_r.powi(2) * h;
        pp[(1, 1)] += q_k.powi(2) * h;
        p.fixed_view_mut::<2, 2>(0, 0).copy_from(&top);
        p.fixed_view_mut::<2, 2>(0, 2).copy_from(&n);
        p.fixed_view_mut::<2, 2>(2, 0).copy_from(&n.transpose());
        p.fixed_view_mut::<2, 2>(2, 2).copy_from(&pp);
        Ok((Vector4::new(next.re, next.im, r_s, k_e), p))
    }
}

/// The standard deviation of white noise on the currents `i_d`, `i_q` \[A\] estimated from
/// a log: the second differences `i[k+1] − 2 i[k] + i[k−1]` of both (variance `6 σ²` for
/// white noise; a smooth current adds little at the sample rates of drive logs), by their
/// median absolute value (`σ = 1.4826 · median/√6`, robust to the steps of the current's
/// reference). Floored at `1e-6` times the current's RMS (and `1e-9` A), so that a
/// noise-free log still gives the filter a positive noise level.
pub fn current_noise(i_d: &[f64], i_q: &[f64]) -> f64 {
    let mut d2: Vec<f64> = [i_d, i_q]
        .iter()
        .flat_map(|x| x.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).abs()))
        .filter(|v| v.is_finite())
        .collect();
    let rms = {
        let (sum, n) =
            [i_d, i_q].iter().flat_map(|x| x.iter()).fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
        if n > 0 { (sum / n as f64).sqrt() } else { 0.0 }
    };
    let floor = (1e-6 * rms).max(1e-9);
    if d2.is_empty() {
        return floor;
    }
    let mid = d2.len() / 2;
    let (_, median, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    (1.4826 * *median / 6f64.sqrt()).max(floor)
}
