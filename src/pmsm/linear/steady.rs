//! The steady-state fit of slow logs (issue 32, part 2): the dq voltage equations without
//! the derivative term, for logs whose sample time is long against the electrical time
//! constant L/R (a host logger at 100 Hz or 2 Hz), where the exact sampled-data model
//! cannot follow the currents between samples.
//!
//! ```text
//! u_d = R_s i_d − ω_e L_q i_q
//! u_q = R_s i_q + ω_e (L_d i_d + ψ_f),   ω_e ψ_f = √(2/3) ω_m K_e  (MODEL.md, K_e = √(3/2) n_p ψ_f)
//! SPM, θ = (R_s, L_s, K_e):        d [ i_d, −ω_e i_q, 0 ]     q [ i_q, ω_e i_d, √(2/3) ω_m ]
//! IPM, θ = (R_s, L_d, L_q, K_e):   d [ i_d, 0, −ω_e i_q, 0 ]  q [ i_q, ω_e i_d, 0, √(2/3) ω_m ]
//! ```
//!
//! One d and one q row per *steady* sample k: the samples are point samples (a logger
//! reads the drive's latest values), and the equations hold at the instant t_k only when
//! `L di/dt` is negligible there. A sample is steady when neither current moves between its
//! neighbours by more than [`SteadyOptions::steady_sigmas`] times the standard deviation of
//! a difference of two noisy samples (`√2 σ_i`, σ_i per current and experiment from the
//! lower quantile of the sample-to-sample changes, which the steady samples dominate).
//!
//! Errors in variables: the currents and the speed are regressors with noise, and the drive
//! answers the current noise of sample k in the voltage it applies right after it, so the
//! equation error of sample k is correlated with its own regressors and least squares is
//! biased. The instruments are the regressors formed from the mean of the neighbouring
//! samples k − 1 and k + 1 (their noise is independent of sample k's; at a steady sample
//! they see the same operating point, and a linear drift averages out), solved by
//! [`crate::estimate::iv::IvSums`] (Söderström & Stoica, *System Identification*, 1989, 8.2),
//! with its covariance: white, or batch means when the equation errors are not white.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::Uncertainty;
use crate::estimate::iv::IvSums;
use crate::pmsm::log::signals::{DqView, check_pole_pairs};
use crate::pmsm::model::interval::SQRT_2_3;
use crate::pmsm::model::kind::MotorKind;
use serde::{Deserialize, Serialize};
use std::fmt;

/// Options of [`steady_state`]. Plain data with defaults; serialisable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SteadyOptions {
    /// A sample is steady when each current changes by at most this many `√2 σ_i` to
    /// either neighbour (σ_i the current's noise, estimated per experiment). Default 4:
    /// a steady sample is rejected with probability ≈ 2 × 6e-5 per current.
    pub steady_sigmas: f64,
    /// Floor of the change allowed \[A\] relative to the peak current, for noise-free logs
    /// (σ_i = 0). Default 1e-4.
    pub relative_floor: f64,
}

impl Default for SteadyOptions {
    fn default() -> Self {
        Self { steady_sigmas: 4.0, relative_floor: 1e-4 }
    }
}

/// The result of [`steady_state`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SteadyEstimate {
    /// The model (SPM: `r_s, l_s, k_e`; IPM: `r_s, l_d, l_q, k_e`).
    pub kind: MotorKind,
    /// Parameter names, length n_θ.
    pub names: Vec<String>,
    /// Parameter units, length n_θ.
    pub units: Vec<String>,
    /// Estimates θ̂ \[Ω, H, V s/rad\], length n_θ.
    pub theta: Vec<f64>,
    /// Standard errors of θ̂ (units of θ̂), length n_θ.
    pub std_error: Vec<f64>,
    /// Half widths of the 95 % intervals (units of θ̂), length n_θ.
    pub ci95: Vec<f64>,
    /// How the covariance was formed.
    pub uncertainty: Uncertainty,
    /// Samples used (steady, with steady neighbours), all experiments.
    pub steady_samples: usize,
    /// Samples in all experiments.
    pub samples: usize,
    /// Current noise σ_i estimated per experiment \[A\], `[d, q]` each.
    pub current_noise: Vec<[f64; 2]>,
    /// What the steady samples cannot tell (a parameter whose relative standard error
    /// exceeds [`UNIDENTIFIABLE`], with the reason in the motor's terms).
    pub notes: Vec<String>,
}

/// Relative standard error above which a parameter is named not identifiable at steady state.
pub const UNIDENTIFIABLE: f64 = 0.1;

/// z of the 20 % quantile of |N(0, 1)|: `P(|Z| ≤ 0.2533) = 0.2`.
const Q20_ABS_NORMAL: f64 = 0.2533;

impl SteadyEstimate {
    /// Estimate of parameter `name` \[SI\], if the model has it.
    pub fn value(&self, name: &str) -> Option<f64> {
        self.names.iter().position(|n| n == name).map(|i| self.theta[i])
    }

    /// `(estimate, 95 % half width)` of parameter `name` \[SI\], if the model has it.
    pub fn interval(&self, name: &str) -> Option<(f64, f64)> {
        self.names.iter().position(|n| n == name).map(|i| (self.theta[i], self.ci95[i]))
    }
}

impl fmt::Display for SteadyEstimate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "steady-state {} ({} of {} samples steady; instruments: neighbouring samples; covariance {:?})",
            self.kind.model_name(),
            self.steady_samples,
            self.samples,
            self.uncertainty.method
        )?;
        for i in 0..self.names.len() {
            writeln!(
                f,
                "  {:<4} = {:.6e} ± {:.2e} {}",
                self.names[i], self.theta[i], self.ci95[i], self.units[i]
            )?;
        }
        for n in &self.notes {
            writeln!(f, "  note: {n}")?;
        }
        Ok(())
    }
}

/// The d and q rows at currents `(i_d, i_q)` \[A\] and mechanical speed `w_m` \[rad/s\].
fn rows(kind: MotorKind, np: f64, i_d: f64, i_q: f64, w_m: f64) -> ([f64; 4], [f64; 4]) {
    let w_e = np * w_m;
    match kind {
        MotorKind::Spm => ([i_d, -w_e * i_q, 0.0, 0.0], [i_q, w_e * i_d, SQRT_2_3 * w_m, 0.0]),
        MotorKind::Ipm => ([i_d, 0.0, -w_e * i_q, 0.0], [i_q, w_e * i_d, 0.0, SQRT_2_3 * w_m]),
    }
}

/// Noise σ \[A\] of a sampled current from the lower 20 % quantile of `|x[k+1] − x[k]|`.
fn noise_sigma(x: &[f64]) -> f64 {
    let mut d: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|v| v.is_finite()).collect();
    if d.is_empty() {
        return 0.0;
    }
    let k = d.len() / 5;
    let (_, q, _) = d.select_nth_unstable_by(k, f64::total_cmp);
    *q / (Q20_ABS_NORMAL * std::f64::consts::SQRT_2)
}

/// Indices k of the steady samples of one experiment (both neighbours exist and neither
/// current moves to them by more than its threshold).
fn steady_indices(i_d: &[f64], i_q: &[f64], thr: [f64; 2]) -> Vec<usize> {
    let n = i_d.len().min(i_q.len());
    (1..n.saturating_sub(1))
        .filter(|&k| {
            [(i_d, thr[0]), (i_q, thr[1])]
                .iter()
                .all(|(x, t)| (x[k] - x[k - 1]).abs() <= *t && (x[k + 1] - x[k]).abs() <= *t)
        })
        .collect()
}

/// Sums of the IV equations at θ over the steady samples (`steady[e]` of experiment e).
fn sums(
    views: &[DqView<'_>],
    steady: &[Vec<usize>],
    kind: MotorKind,
    np: f64,
    theta: &[f64],
) -> Result<IvSums> {
    let nth = kind.parameter_names().len();
    let mut acc = IvSums::new(2, nth);
    let (mut d, mut z) = (vec![0.0; 2 * nth], vec![0.0; 2 * nth]);
    for (v, ks) in views.iter().zip(steady) {
        let (u_d, u_q) = v.terminal_voltage()?;
        let (i_d, i_q, w_m) = (v.i_d(), v.i_q(), v.w_m());
        acc.start_experiment();
        for &k in ks {
            let (rd, rq) = rows(kind, np, i_d[k], i_q[k], w_m[k]);
            let mean = |x: &[f64]| 0.5 * (x[k - 1] + x[k + 1]);
            let (zd, zq) = rows(kind, np, mean(i_d), mean(i_q), mean(w_m));
            let dot = |r: &[f64; 4]| r[..nth].iter().zip(theta).map(|(a, b)| a * b).sum::<f64>();
            let eps = [u_d[k] - dot(&rd), u_q[k] - dot(&rq)];
            for j in 0..nth {
                (d[j], d[nth + j]) = (-rd[j], -rq[j]);
                (z[j], z[nth + j]) = (-zd[j], -zq[j]);
            }
            acc.add(&eps, &d, &z);
        }
        acc.end_experiment();
    }
    Ok(acc)
}

/// The steady-state fit of `experiments` (one motor, `n_p` pole pairs, model `kind`): R_s,
/// L (SPM) or L_d, L_q (IPM), K_e \[Ω, H, V s/rad\] by instrumental variables on the steady
/// samples (module documentation), with 95 % intervals and the notes on what is not
/// identifiable. Needs channels `ud, uq, id, iq, w_m` (the terminal voltage; point samples).
///
/// # Errors
/// [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError) for `n_p` out of range;
/// [`Error::InvalidOption`] for non-positive options;
/// [`Error::MissingChannel`] for a log without the dq channels or the terminal voltage;
/// [`Error::Numerical`] when fewer steady samples than parameters remain, or they do not
/// determine every parameter (e.g. no speed at all).
pub fn steady_state(
    experiments: &[Experiment],
    n_p: u32,
    kind: MotorKind,
    options: &SteadyOptions,
) -> Result<SteadyEstimate> {
    check_pole_pairs(n_p)?;
    if !(options.steady_sigmas.is_finite() && options.steady_sigmas > 0.0) {
        return Err(Error::InvalidOption {
            option: "steady_sigmas".into(),
            reason: format!("{} is not a positive number", options.steady_sigmas),
        });
    }
    if !(options.relative_floor.is_finite() && options.relative_floor >= 0.0) {
        return Err(Error::InvalidOption {
            option: "relative_floor".into(),
            reason: format!("{} is not a non-negative number", options.relative_floor),
        });
    }
    let views = experiments.iter().map(DqView::try_new).collect::<Result<Vec<_>>>()?;
    let mut steady = Vec::with_capacity(views.len());
    let mut current_noise = Vec::with_capacity(views.len());
    for v in &views {
        v.terminal_voltage()?;
        let sigma = [noise_sigma(v.i_d()), noise_sigma(v.i_q())];
        let floor = options.relative_floor * v.peak_current();
        let thr = sigma.map(|s| (options.steady_sigmas * std::f64::consts::SQRT_2 * s).max(floor));
        steady.push(steady_indices(v.i_d(), v.i_q(), thr));
        current_noise.push(sigma);
    }
    let nth = kind.parameter_names().len();
    let used: usize = steady.iter().map(Vec::len).sum();
    if used <= nth {
        return Err(Error::Numerical {
            context: "steady-state fit".into(),
            reason: format!(
                "{used} steady samples for {nth} parameters: the log never settles between samples"
            ),
        });
    }
    let np = f64::from(n_p);
    // The equations are linear in θ: one IV step from zero is the IV solution.
    let mut theta = vec![0.0; nth];
    let step = sums(&views, &steady, kind, np, &theta)?.step()?;
    theta.iter_mut().zip(step.iter()).for_each(|(t, s)| *t += s);
    let cov = sums(&views, &steady, kind, np, &theta)?.covariance()?;
    let t = cov.t_quantile();
    let std_error: Vec<f64> = (0..nth).map(|i| cov.cov[(i, i)].max(0.0).sqrt()).collect();
    let names: Vec<String> = kind.parameter_names().iter().map(|s| (*s).to_string()).collect();
    let notes = notes(kind, &names, &theta, &std_error);
    Ok(SteadyEstimate {
        kind,
        units: kind.parameter_units().iter().map(|s| (*s).to_string()).collect(),
        ci95: std_error.iter().map(|s| t * s).collect(),
        names,
        theta,
        std_error,
        uncertainty: cov.uncertainty,
        steady_samples: used,
        samples: views.iter().map(DqView::len).sum(),
        current_noise,
        notes,
    })
}

/// The parameters the steady samples leave undetermined (relative standard error above
/// [`UNIDENTIFIABLE`]), each with what it would take.
fn notes(kind: MotorKind, names: &[String], theta: &[f64], se: &[f64]) -> Vec<String> {
    let why = |name: &str| match (kind, name) {
        (_, "r_s") => {
            "at steady state R_s is seen only through R_s i against the back-EMF; at high speed u ≫ R_s i: add steady samples at low speed and high current"
        }
        (MotorKind::Ipm, "l_d") => {
            "L_d enters only as ω_e L_d i_d: with i_d ≈ 0 it is not identifiable; add steady samples with d-current injection"
        }
        (MotorKind::Ipm, "l_q") | (MotorKind::Spm, "l_s") => {
            "L_q enters only as ω_e L_q i_q: it needs load current at speed"
        }
        _ => "K_e needs steady samples at speed",
    };
    names
        .iter()
        .zip(theta.iter().zip(se))
        .filter(|(_, (t, s))| s.is_nan() || **s > UNIDENTIFIABLE * t.abs())
        .map(|(n, _)| format!("{n} not identifiable from these steady samples: {}", why(n)))
        .collect()
}
