//! An observer run over a whole log, the MRAS ([`track`]) or the Kalman filter
//! ([`track_kalman`]): the estimates' trajectory (backs `greybox track`).

use super::config::MrasConfig;
use super::kalman::{Kalman, KalmanNoise, current_noise};
use super::mras::{Estimates, Mras, Sample};
use crate::data::Experiment;
use crate::error::Result;
use crate::pmsm::{DqView, ThermalReference};
use serde::{Deserialize, Serialize};

/// The estimates over time, one point per sample interval (all vectors of one length).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Time of each point `t_k = k h` \[s\], length M.
    pub t: Vec<f64>,
    /// K̂_e after the sample at `t_k` \[V s/rad\], length M.
    pub k_e: Vec<f64>,
    /// R̂_s after the sample at `t_k` \[Ω\], length M.
    pub r_s: Vec<f64>,
    /// Standard error of K̂_e \[V s/rad\], length M; empty for an observer without one
    /// (the MRAS).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub k_e_se: Vec<f64>,
    /// Standard error of R̂_s \[Ω\], length M; empty for an observer without one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub r_s_se: Vec<f64>,
    /// The run's self-check (1 when its model and noise levels are right; see
    /// [`INNOVATION_RATIO_LIMIT`]): for the Kalman filter the mean normalised innovation
    /// squared over the second half of the run, halved; for the MRAS the mean square of the
    /// model's one-step prediction error from the measured current at the running estimates
    /// over the second half, over `4σ²` (σ the log's current noise, [`current_noise`]; the
    /// error of each component has the variance `2σ²` when the model is right). `None` for a
    /// run too short to have one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub innovation_ratio: Option<f64>,
    /// The estimates after the last sample.
    pub final_estimate: Estimates,
}

impl Trajectory {
    /// At most `max_points` points, evenly strided from the first, always keeping the
    /// last (`max_points` 0 or 1: the last point only; an empty trajectory stays empty).
    /// `final_estimate` is kept.
    pub fn decimate(&self, max_points: usize) -> Trajectory {
        let n = self.t.len();
        let idx: Vec<usize> = match (n, max_points) {
            (0, _) => Vec::new(),
            (_, m) if m >= n => (0..n).collect(),
            (_, 0 | 1) => vec![n - 1],
            (_, m) => {
                let stride = (n - 1).div_ceil(m - 1);
                let mut v: Vec<usize> = (0..n).step_by(stride).collect();
                if v.last() != Some(&(n - 1)) {
                    v.push(n - 1);
                }
                v
            }
        };
        let pick = |x: &[f64]| if x.is_empty() { Vec::new() } else { idx.iter().map(|&k| x[k]).collect() };
        Trajectory {
            t: pick(&self.t),
            k_e: pick(&self.k_e),
            r_s: pick(&self.r_s),
            k_e_se: pick(&self.k_e_se),
            r_s_se: pick(&self.r_s_se),
            innovation_ratio: self.innovation_ratio,
            final_estimate: self.final_estimate,
        }
    }

    /// The standard errors `(K̂_e, R̂_s)` after the last sample; `None` for an observer
    /// without them (or an empty trajectory).
    pub fn final_se(&self) -> Option<(f64, f64)> {
        Some((*self.k_e_se.last()?, *self.r_s_se.last()?))
    }
}

/// Runs the MRAS over a PMSM log (channels `id, iq, ud, uq, w_m` through [`DqView`]):
/// sample k pairs `i[k]` with `u[k]` and the interval-mean speed
/// `(ω_m[k] + ω_m[k+1])/2` of the step to `i[k+1]` (MODEL.md §4), k = 0..N−2.
/// The sample time is the log's (`config.h` is replaced by it).
///
/// # Errors
/// Those of [`DqView::try_new`] (a missing channel, too short a log) and
/// [`DqView::terminal_voltage`] (a log with only the voltage reference), of
/// [`MrasConfig::validate`] and of [`Mras::update`] (naming the sample).
pub fn track(e: &Experiment, config: &MrasConfig) -> Result<Trajectory> {
    let v = DqView::try_new(e)?;
    let mut mras = Mras::try_new(MrasConfig { h: e.h(), ..config.clone() })?;
    let (u_d, u_q) = v.terminal_voltage()?;
    let (i_d, i_q, w_m) = (v.i_d(), v.i_q(), v.w_m());
    let m = v.len() - 1;
    let mut out = Trajectory {
        t: Vec::with_capacity(m),
        k_e: Vec::with_capacity(m),
        r_s: Vec::with_capacity(m),
        final_estimate: mras.output(),
        ..Trajectory::default()
    };
    // The self-check: the model's one-step prediction from the measured current at the
    // running estimates, against the next measured current, over the second half.
    let mut square = 0.0;
    for k in 0..m {
        let s =
            Sample { i_d: i_d[k], i_q: i_q[k], u_d: u_d[k], u_q: u_q[k], w_m: 0.5 * (w_m[k] + w_m[k + 1]) };
        let est = mras.update(&s)?;
        if k >= m / 2 {
            let (p_d, p_q) = mras.one_step(&s, &est)?;
            square += (i_d[k + 1] - p_d).powi(2) + (i_q[k + 1] - p_q).powi(2);
        }
        out.t.push(e.t0() + k as f64 * e.h());
        out.k_e.push(est.k_e);
        out.r_s.push(est.r_s);
        out.final_estimate = est;
    }
    let half = m - m / 2;
    // White current noise σ on both samples of a step: each component's prediction error has
    // the variance 2σ² (the step's transition within h of the identity), the mean square of
    // both 4σ².
    let sigma = current_noise(i_d, i_q);
    out.innovation_ratio = (half > 0).then(|| square / (4.0 * sigma * sigma * half as f64));
    Ok(out)
}

/// Runs the extended Kalman filter ([`Kalman`]) over a PMSM log as [`track`] runs the MRAS
/// (the same samples, `config.h` replaced by the log's sample time), with the noise model
/// `noise`, or by default [`KalmanNoise::for_machine`] at the current noise the log shows
/// ([`current_noise`]) and the configured `r_s0`, `k_e0`. The trajectory carries the
/// standard errors.
///
/// # Errors
/// Those of [`track`], [`KalmanNoise::validate`] and [`Kalman::update`] (naming the sample).
pub fn track_kalman(e: &Experiment, config: &MrasConfig, noise: Option<KalmanNoise>) -> Result<Trajectory> {
    track_kalman_with(e, config, |i_d, i_q| {
        Ok(noise
            .unwrap_or_else(|| KalmanNoise::for_machine(current_noise(i_d, i_q), config.r_s0, config.k_e0)))
    })
}

/// [`track_kalman`] with the noise model from `noise`, given the log's currents `i_d`,
/// `i_q` \[A\] (each of the log's length) as the filter reads them: the log's channels are
/// checked and viewed once.
///
/// # Errors
/// Those of [`track_kalman`] and of `noise`.
pub fn track_kalman_with(
    e: &Experiment,
    config: &MrasConfig,
    noise: impl FnOnce(&[f64], &[f64]) -> Result<KalmanNoise>,
) -> Result<Trajectory> {
    let v = DqView::try_new(e)?;
    let (u_d, u_q) = v.terminal_voltage()?;
    let (i_d, i_q, w_m) = (v.i_d(), v.i_q(), v.w_m());
    let noise = noise(i_d, i_q)?;
    let mut filter = Kalman::try_new(MrasConfig { h: e.h(), ..config.clone() }, noise)?;
    let m = v.len() - 1;
    let mut out = Trajectory {
        t: Vec::with_capacity(m),
        k_e: Vec::with_capacity(m),
        r_s: Vec::with_capacity(m),
        k_e_se: Vec::with_capacity(m),
        r_s_se: Vec::with_capacity(m),
        innovation_ratio: None,
        final_estimate: Estimates::default(),
    };
    let mut nis = 0.0;
    for k in 0..m {
        let s =
            Sample { i_d: i_d[k], i_q: i_q[k], u_d: u_d[k], u_q: u_q[k], w_m: 0.5 * (w_m[k] + w_m[k + 1]) };
        let est = filter.update(&s)?;
        out.t.push(e.t0() + k as f64 * e.h());
        out.k_e.push(est.estimates.k_e);
        out.r_s.push(est.estimates.r_s);
        out.k_e_se.push(est.k_e_se);
        out.r_s_se.push(est.r_s_se);
        out.final_estimate = est.estimates;
        if k >= m / 2 {
            nis += est.nis;
        }
    }
    let half = m - m / 2;
    out.innovation_ratio = (half > 0).then(|| nis / (2.0 * half as f64));
    Ok(out)
}

/// The largest [`Trajectory::innovation_ratio`] of a trusted run: the filter's innovations'
/// (the MRAS's one-step prediction errors') mean square at most 4 times what the model
/// predicts. Measured, the filter: 0.77 and 0.97 on the shared noisy logs tracked with their
/// fits' reports (current noise as the log shows it), 0.001–0.07 on the noise-free ones (the
/// noise level estimated from the second differences then exceeds the innovations); 55 on a
/// PWM log whose ripple the model lacks (`K_e` 3 % off, its interval 0.25 %), 5·10⁹ with a
/// wrong inductance (`K_e` 4·10⁴ times the truth). The MRAS: 0.80 and 0.97 on the noisy
/// logs, 0.00–0.13 on the noise-free ones; 12 and 20 on the noisy logs with the inductances
/// doubled (`K_e` +44 % and +277 %), 3·10⁴ on a stator-held reading of a dq-held log, 6–30
/// on the surface-magnet PWM logs. Over half a log of thousands of samples the mean of
/// χ²₂/2 is 1 within a few percent.
pub const INNOVATION_RATIO_LIMIT: f64 = 4.0;

impl Trajectory {
    /// Whether the run passes its self-check: no [`Trajectory::innovation_ratio`] (a run
    /// too short for one), or one at most [`INNOVATION_RATIO_LIMIT`].
    pub fn consistent(&self) -> bool {
        self.innovation_ratio.is_none_or(|r| r <= INNOVATION_RATIO_LIMIT)
    }
}

/// Winding and magnet temperatures over a trajectory \[°C\] with their standard errors
/// (`NaN` where the trajectory has none: the MRAS), from `R̂_s(t)` and `ψ̂_f(t)` by the
/// offline fit's conventions ([`ThermalReference::temperatures`], MODEL.md §3): each vector
/// empty when its reference value (`r_s0`, `psi_f0`) is not given, else of the
/// trajectory's length.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TemperatureTrajectory {
    /// Winding temperature \[°C\].
    pub t_winding: Vec<f64>,
    /// Its standard error \[K\].
    pub t_winding_se: Vec<f64>,
    /// Magnet temperature \[°C\].
    pub t_magnet: Vec<f64>,
    /// Its standard error \[K\].
    pub t_magnet_se: Vec<f64>,
}

impl Trajectory {
    /// The temperatures of every point for a machine of `n_p` pole pairs (`ψ_f = √(2/3)
    /// K_e / n_p`) at the reference `reference` (see [`TemperatureTrajectory`]).
    pub fn temperatures(&self, n_p: u32, reference: &ThermalReference) -> TemperatureTrajectory {
        let psi = crate::pmsm::SQRT_2_3 / f64::from(n_p.max(1));
        let mut out = TemperatureTrajectory::default();
        for k in 0..self.t.len() {
            let se = |v: &[f64]| v.get(k).copied().unwrap_or(f64::NAN);
            let (se_r, se_k) = (se(&self.r_s_se), se(&self.k_e_se));
            for d in reference.temperatures(self.r_s[k], se_r, psi * self.k_e[k], psi * se_k, None) {
                let (value, std) = match d.name.as_str() {
                    "t_winding" => (&mut out.t_winding, &mut out.t_winding_se),
                    _ => (&mut out.t_magnet, &mut out.t_magnet_se),
                };
                value.push(d.value);
                std.push(d.std_error);
            }
        }
        out
    }
}
