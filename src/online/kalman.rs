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
use super::mras::{Estimates, Machine, Sample, estimates, invalid, machine, settings};
use crate::error::{Error, Result};
use greybox_observer::{Fault, Field, Noise};
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
pub const MODEL_NOISE_RATIO: f64 = greybox_observer::MODEL_NOISE_RATIO;
/// `q_R / R_s0` of [`KalmanNoise::for_machine`] \[1/√s\]: 3 % of `R_s` per √s.
pub const R_S_WALK: f64 = greybox_observer::R_S_WALK;
/// `q_K / K_e0` of [`KalmanNoise::for_machine`] \[1/√s\]: 0.2 % of `K_e` per √s.
pub const K_E_WALK: f64 = greybox_observer::K_E_WALK;

impl KalmanNoise {
    /// The default noise model of a machine started at `r_s0` \[Ω\], `k_e0` \[V s/rad\],
    /// with current noise `sigma_i` \[A\]: `q_i = 0.01 σ_i` ([`MODEL_NOISE_RATIO`]), walks
    /// relative to the present estimates, `q_R = 0.03 R̂_s/√s` ([`R_S_WALK`]) and
    /// `q_K = 0.002 |K̂_e|/√s` ([`K_E_WALK`]), initial standard deviations half of `R_s0`
    /// and a fifth of `K_e0` (a start without a value, 0, counts as 1 Ω and 0.1 V s/rad).
    pub fn for_machine(sigma_i: f64, r_s0: f64, k_e0: f64) -> Self {
        Self::from(Noise::for_machine(sigma_i, r_s0, k_e0))
    }

    /// The walks' intensities `(q_R \[Ω/√s\], q_K \[V s/rad/√s\])` at the estimates
    /// `r_s` \[Ω\], `k_e` \[V s/rad\]: the fields themselves, or with `relative` those
    /// fractions of the estimates (floored, see `relative`).
    pub fn walks_at(&self, r_s: f64, k_e: f64) -> (f64, f64) {
        Noise::from(*self).walks_at(r_s, k_e)
    }

    /// # Errors
    /// [`Error::InvalidOption`] naming the field: `sigma_i`, `p0_r_s`, `p0_k_e` not
    /// positive and finite; `q_i`, `q_r_s`, `q_k_e` negative or not finite.
    pub fn validate(&self) -> Result<()> {
        // The rule is the observer crate's (`Noise::invalid`); the message names the value.
        let Some(field) = Noise::from(*self).invalid() else { return Ok(()) };
        let (v, what) = match field {
            Field::SigmaI => (self.sigma_i, "positive and finite"),
            Field::P0RS => (self.p0_r_s, "positive and finite"),
            Field::P0KE => (self.p0_k_e, "positive and finite"),
            Field::QI => (self.q_i, "finite and at least 0"),
            Field::QRS => (self.q_r_s, "finite and at least 0"),
            _ => (self.q_k_e, "finite and at least 0"),
        };
        Err(Error::InvalidOption { option: field.name().into(), reason: format!("must be {what}, got {v}") })
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
    /// The normalised innovation squared `νᵀ S⁻¹ ν` (χ²₂ when the model and the noise are
    /// right; 0 at the first sample).
    #[serde(default)]
    pub nis: f64,
}

impl From<Noise<f64>> for KalmanNoise {
    fn from(n: Noise<f64>) -> Self {
        let Noise { sigma_i, q_i, q_r_s, q_k_e, p0_r_s, p0_k_e, relative } = n;
        Self { sigma_i, q_i, q_r_s, q_k_e, p0_r_s, p0_k_e, relative }
    }
}

impl From<KalmanNoise> for Noise<f64> {
    fn from(n: KalmanNoise) -> Self {
        let KalmanNoise { sigma_i, q_i, q_r_s, q_k_e, p0_r_s, p0_k_e, relative } = n;
        Self { sigma_i, q_i, q_r_s, q_k_e, p0_r_s, p0_k_e, relative }
    }
}

/// The extended Kalman filter (module doc), one sample at a time, without allocation: the
/// filter of [`greybox_observer::Kalman`] (`no_std`, for firmware), here with the salient
/// step too.
#[derive(Clone, Debug)]
pub struct Kalman {
    core: greybox_observer::Kalman<f64, Machine>,
    config: MrasConfig,
}

impl Kalman {
    /// A filter of the machine of `config` (`n_p`, `l_s`, `l_q`, `h`, `hold`, the initial
    /// `k_e0`, `r_s0`; the MRAS's gains are not used) with the noise model `noise`.
    ///
    /// # Errors
    /// Those of [`MrasConfig::validate`] and [`KalmanNoise::validate`].
    pub fn try_new(config: MrasConfig, noise: KalmanNoise) -> Result<Self> {
        noise.validate()?;
        let config = MrasConfig { adaptation: super::Adaptation::Lyapunov, ..config };
        config.validate()?;
        let settings = settings(&config);
        let core = greybox_observer::Kalman::new(settings, machine(&config, &settings)?, noise.into())
            .map_err(invalid)?;
        Ok(Self { core, config })
    }

    /// The machine's settings.
    pub fn config(&self) -> &MrasConfig {
        &self.config
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
        let x = greybox_observer::Sample { i_d: s.i_d, i_q: s.i_q, u_d: s.u_d, u_q: s.u_q, w_m: s.w_m };
        match self.core.update(&x) {
            Ok(e) => Ok(KalmanEstimate {
                estimates: estimates(&e),
                k_e_se: e.k_e_se,
                r_s_se: e.r_s_se,
                nis: e.nis,
            }),
            Err(Fault::NonFinite { channel, sample }) => {
                let (column, value) =
                    [("id", s.i_d), ("iq", s.i_q), ("ud", s.u_d), ("uq", s.u_q), ("w_m", s.w_m)]
                        [channel.min(4)];
                Err(Error::NonFinite { column: column.into(), row: sample as usize, value })
            }
            Err(fault) => {
                let (sample, reason) = match fault {
                    Fault::Singular { sample, .. } => (sample, "innovation covariance singular".to_string()),
                    Fault::NotFinite { sample, k_e, r_s } => {
                        (sample, format!("state or covariance not finite (k_e = {k_e}, r_s = {r_s})"))
                    }
                    Fault::Step { sample, error } => (sample, error.to_string()),
                    Fault::NonFinite { sample, .. } | Fault::Stale { output: sample, .. } => {
                        (sample, "not expected".to_string())
                    }
                };
                Err(Error::Numerical { context: format!("Kalman filter at sample {sample}"), reason })
            }
        }
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
