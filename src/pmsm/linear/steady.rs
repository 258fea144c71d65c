//! The steady-state fit of slow logs (issues 32 and 43): the dq voltage equations with the
//! currents' drift at the log's rate, for logs whose sample time is long against the
//! electrical time constant L/R (a host logger at 100 Hz or 2 Hz), where the exact
//! sampled-data model cannot follow the currents between samples.
//!
//! ```text
//! u_d = R_s i_d + L_d di_d/dt − ω_e L_q i_q
//! u_q = R_s i_q + L_q di_q/dt + ω_e (L_d i_d + ψ_f),   ω_e ψ_f = √(2/3) ω_m K_e  (MODEL.md, K_e = √(3/2) n_p ψ_f)
//! SPM, θ = (R_s, L_s, K_e):        d [ i_d, di_d/dt − ω_e i_q, 0 ]     q [ i_q, di_q/dt + ω_e i_d, √(2/3) ω_m ]
//! IPM, θ = (R_s, L_d, L_q, K_e):   d [ i_d, di_d/dt, −ω_e i_q, 0 ]     q [ i_q, ω_e i_d, di_q/dt, √(2/3) ω_m ]
//! ```
//!
//! and, without `--control-period`, the nuisance `h_c2 = h_c²` \[s²\] of the control
//! period's first-order effect ([`super::steady_model`]).
//!
//! One d and one q row per *steady* sample k: the samples are point samples (a logger
//! reads the drive's latest values), and the equations (with the currents' drift `L di/dt`
//! from central differences at the log's rate, [`super::steady_model`]) hold at the
//! instant t_k when the currents vary smoothly across the samples `k − 1, k, k + 1`: a
//! plateau or a ramp, not a step. A sample is steady when the second differences
//! `i[j+1] − 2 i[j] + i[j−1]` at j = k − 1, k, k + 1 of neither current exceed
//! [`SteadyOptions::steady_sigmas`] times their standard deviation for white noise
//! (`√6 σ_i`, σ_i per current and experiment from the lower quantile of the second
//! differences, which the smooth samples dominate): the stencil `k − 2 … k + 2` that the
//! equation and its instruments read lies on one smooth stretch. The second difference at k
//! alone let in, as σ_i grew, samples on the curved tail after a step, where the central
//! difference's error `L (d³i/dt³) h²/6` biased the interior-magnet fit; a log with fewer
//! than `FEWEST_STENCILS` (128) such samples falls back to k alone, with a note.
//! A real drive cycle has short plateaus and ramps; the constant-current rule this replaces
//! kept ramp samples whose `L di/dt` it did not model (R_s +0.5 % at |z| 19 on every 40th
//! row of a 10 kHz log of moves).
//!
//! Errors in variables: the currents and the speed are regressors with noise, and the drive
//! answers the current noise of sample k in the voltage it applies right after it, so the
//! equation error of sample k is correlated with its own regressors and least squares is
//! biased. The instruments are the regressors formed from samples k − 2 and k + 2 (their
//! mean and slope: their noise is independent of samples k − 1 … k + 1, which the equation
//! error holds; at a smooth sample they see the same operating point), solved by
//! [`crate::estimate::iv::IvSums`] (Söderström & Stoica, *System Identification*, 1989, 8.2),
//! with its covariance: white, or batch means when the equation errors are not white
//! (blocks short enough for 32 batches on a short log).

use super::steady_model::SteadyLog;
use super::steady_samples::{FEWEST_STENCILS, SQRT_6, noise_sigma, steady_indices};
pub use super::steady_solve::{PERIOD_TERM, SteadyOptions};
use super::steady_solve::{Solved, period_note, solve};
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::Uncertainty;
use crate::pmsm::log::DqLogs;
use crate::pmsm::log::signals::check_pole_pairs;
use crate::pmsm::model::kind::MotorKind;
use serde::{Deserialize, Serialize};
use std::fmt;

/// The result of [`steady_state`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SteadyEstimate {
    /// The model (SPM: `r_s, l_s, k_e`; IPM: `r_s, l_d, l_q, k_e`; then the nuisance
    /// `h_c2` \[s²\] when estimated, see [`SteadyOptions::control_period`]).
    pub kind: MotorKind,
    /// Parameter names, length n_θ (per-log parameters once per log).
    pub names: Vec<String>,
    /// The log of each per-log parameter (`None`: shared), length n_θ.
    pub experiment: Vec<Option<String>>,
    /// IV iterations made (the small terms of the period and the exact control period's
    /// equations are evaluated at the previous estimate).
    pub iterations: usize,
    /// Whether the iteration's step fell below its tolerance (else it stopped at its
    /// iteration limit: the fit is reported as not converged).
    #[serde(default = "converged_default")]
    pub converged: bool,
    /// The control period the equations assumed \[s\] (`None`: estimated or neglected).
    pub control_period: Option<f64>,
    /// Parameter units, length n_θ.
    pub units: Vec<String>,
    /// Estimates θ̂ \[Ω, H, V s/rad; s² for `h_c2`\], length n_θ.
    pub theta: Vec<f64>,
    /// Standard errors of θ̂ (units of θ̂), length n_θ.
    pub std_error: Vec<f64>,
    /// Half widths of the 95 % intervals (units of θ̂), length n_θ.
    pub ci95: Vec<f64>,
    /// How the covariance was formed.
    pub uncertainty: Uncertainty,
    /// Samples used (smooth, with samples k ± 2 in the log), all experiments.
    pub steady_samples: usize,
    /// Samples in all experiments.
    pub samples: usize,
    /// Current noise σ_i estimated per experiment \[A\], `[d, q]` each.
    pub current_noise: Vec<[f64; 2]>,
    /// The white-noise standard errors (units of θ̂), length n_θ.
    pub std_error_white: Vec<f64>,
    /// Correlation of the estimates (n_θ × n_θ).
    pub correlation: Vec<Vec<f64>>,
    /// Whiteness of the d and q equation errors over the steady samples.
    pub whiteness: Vec<crate::estimate::metrics::Whiteness>,
    /// RMS equation error of the d and q voltages over the steady samples \[V\].
    pub rms_residual: [f64; 2],
    /// NRMSE fit of the d and q voltages over the steady samples \[%\].
    pub fit_percent: [f64; 2],
    /// What the steady samples cannot tell (a parameter whose relative standard error
    /// exceeds [`UNIDENTIFIABLE`], with the reason in the motor's terms).
    pub notes: Vec<String>,
}

/// Reports written before the field existed converged.
fn converged_default() -> bool {
    true
}

/// Widest half width of the central differences ([`SteadyOptions::derivative_half_width`]),
/// in samples: 4. Its truncation error is 16 times the default's, and its instruments read
/// samples 5 away, beyond any smooth stretch of telemetry the steady-sample rule keeps.
pub(crate) const MAX_DERIVATIVE_HALF_WIDTH: usize = 4;

/// Relative standard error above which a parameter is named not identifiable at steady state.
pub const UNIDENTIFIABLE: f64 = 0.1;

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
            "steady-state {} ({} of {} samples smooth; instruments: samples k ± 2; covariance {:?})",
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

/// Checks the options' numbers.
fn check_options(options: &SteadyOptions, kind: MotorKind) -> Result<()> {
    let bad = |option: &str, reason: String| Err(Error::InvalidOption { option: option.into(), reason });
    if !(options.steady_sigmas.is_finite() && options.steady_sigmas > 0.0) {
        return bad("steady_sigmas", format!("{} is not a positive number", options.steady_sigmas));
    }
    if !(options.relative_floor.is_finite() && options.relative_floor >= 0.0) {
        return bad("relative_floor", format!("{} is not a non-negative number", options.relative_floor));
    }
    if let Some(h) = options.control_period.filter(|h| !(h.is_finite() && *h > 0.0)) {
        return bad("control_period", format!("{h} s is not a positive sample time"));
    }
    if !(1..=MAX_DERIVATIVE_HALF_WIDTH).contains(&options.derivative_half_width) {
        return bad(
            "derivative_half_width",
            format!(
                "{} samples is not a half width from 1 to {MAX_DERIVATIVE_HALF_WIDTH}",
                options.derivative_half_width
            ),
        );
    }
    if !(options.cable_resistance.is_finite() && options.cable_resistance >= 0.0) {
        return bad(
            "cable_resistance",
            format!("{} ohm is not a non-negative resistance", options.cable_resistance),
        );
    }
    if let Some(n) = options.per_experiment.iter().find(|n| !kind.parameter_names().contains(&n.as_str())) {
        return bad(
            "per_experiment",
            format!(
                "{n} is not a parameter of the {} model ({})",
                kind.model_name(),
                kind.parameter_names().join(", ")
            ),
        );
    }
    Ok(())
}

/// The steady-state fit of `experiments` (one motor, `n_p` pole pairs, model `kind`): R_s,
/// L (SPM) or L_d, L_q (IPM), K_e \[Ω, H, V s/rad\] by instrumental variables on the steady
/// samples (module documentation), with 95 % intervals and the notes on what is not
/// identifiable. Needs channels `ud, uq, id, iq, w_m` (the terminal voltage; point samples).
///
/// # Errors
/// [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError) for `n_p` out of range;
/// [`Error::InvalidOption`] for non-positive options, a derivatives' half width outside 1–4
/// or an unknown per-log parameter;
/// [`Error::MissingChannel`] for a log without the dq channels or the terminal voltage;
/// [`Error::Numerical`] when the steady samples' equations (two a sample) are no more
/// than the parameters, or they do not determine every parameter (e.g. no speed at all).
pub fn steady_state(
    experiments: &[Experiment],
    n_p: u32,
    kind: MotorKind,
    options: &SteadyOptions,
) -> Result<SteadyEstimate> {
    check_pole_pairs(n_p)?;
    check_options(options, kind)?;
    steady_state_of(&DqLogs::try_new(experiments)?, n_p, kind, options)
}

/// [`steady_state`] of logs validated once where the fit starts.
///
/// # Errors
/// As [`steady_state`].
pub(crate) fn steady_state_of(
    dq: &DqLogs<'_>,
    n_p: u32,
    kind: MotorKind,
    options: &SteadyOptions,
) -> Result<SteadyEstimate> {
    check_pole_pairs(n_p)?;
    check_options(options, kind)?;
    let experiments = dq.experiments();
    let mut logs = Vec::with_capacity(experiments.len());
    let mut current_noise = Vec::with_capacity(experiments.len());
    let fewest = FEWEST_STENCILS;
    let mut narrow = Vec::new();
    for (e, &view) in experiments.iter().zip(dq.views()) {
        view.terminal_voltage()?;
        let sigma = [noise_sigma(view.i_d()), noise_sigma(view.i_q())];
        let floor = options.relative_floor * view.peak_current();
        let thr = sigma.map(|s| (options.steady_sigmas * SQRT_6 * s).max(floor));
        let (mut steady, stencils) = steady_indices(view.i_d(), view.i_q(), thr, fewest);
        // Wider differences read samples k ± (a + 1), which the log's ends lack.
        let a = options.derivative_half_width;
        steady.retain(|&k| k > a && k + a + 1 < view.len());
        if stencils < fewest {
            narrow.push(format!("{} ({stencils} of {fewest})", e.name()));
        }
        logs.push(SteadyLog { view, h: e.h(), steady, columns: Vec::new() });
        current_noise.push(sigma);
    }
    // Two equations a sample, one more than the unknowns at least: a degree of freedom for
    // the noise's estimate (with none, the intervals would have zero width). The control
    // period's term is estimated only where it leaves one too.
    let unknowns = kind.parameter_names().len();
    if let Some(log) = logs.iter().position(|l| 2 * l.steady.len() <= unknowns) {
        return Err(Error::Numerical {
            context: "steady-state fit".into(),
            reason: format!(
                "{} has {} steady samples (two equations each) for {unknowns} unknowns: its currents are seldom \
                 smooth across three samples; a longer log, or one at a faster rate",
                experiments[log].name(),
                logs[log].steady.len(),
            ),
        });
    }
    let estimate = options.estimate_period
        && options.control_period.is_none()
        && logs.iter().all(|l| 2 * l.steady.len() > unknowns + 1);
    let solved = solve(&mut logs, experiments, n_p, kind, options, estimate)?;
    // One speed cannot tell the period's (ω_e h_c)²/12 from K_e: neglected then.
    let solved = match solved.period_confounded(kind) {
        true => solve(&mut logs, experiments, n_p, kind, options, false)?,
        false => solved,
    };
    let Solved { names, experiment, theta, cov, sums, iterations, converged, period } = solved;
    let nth = names.len();
    let std_error: Vec<f64> = (0..nth).map(|i| cov.cov[(i, i)].max(0.0).sqrt()).collect();
    let mut notes = notes(kind, &names, &theta, &std_error);
    if !narrow.is_empty() {
        notes.push(format!(
            "too few samples smooth across k − 2 … k + 2 in {}: the samples smooth across k − 1 … k + 1 taken, whose \
             instruments (samples k ± 2) may lie on a transient and whose equations on the tail of one",
            narrow.join(", ")
        ));
    }
    let applied =
        options.control_period.filter(|_| !matches!(period, super::steady_solve::Period::Unusable(_)));
    notes.extend(period_note(period, &names, &theta, &std_error));
    let units = names.iter().map(|n| unit_of(kind, n).to_string()).collect();
    let used = sums.count;
    let fit = goodness(&logs, &sums.sse);
    Ok(SteadyEstimate {
        kind,
        units,
        ci95: std_error.iter().enumerate().map(|(j, s)| cov.uncertainty.t_quantile_of(j) * s).collect(),
        std_error_white: (0..nth).map(|i| cov.cov_white[(i, i)].max(0.0).sqrt()).collect(),
        correlation: (0..nth)
            .map(|a| (0..nth).map(|b| cov.cov[(a, b)] / (std_error[a] * std_error[b])).collect())
            .collect(),
        names,
        experiment,
        iterations,
        converged,
        control_period: applied,
        theta,
        std_error,
        // The steady-state intervals are `± t·std_error`, widened later by the truncation
        // error (`pmsm::fit::steady_checks`): not the restricted ones.
        uncertainty: Uncertainty { restricted: false, ..cov.uncertainty },
        whiteness: cov.whiteness,
        rms_residual: fit.0,
        fit_percent: fit.1,
        steady_samples: used,
        samples: logs.iter().map(|l| l.view.len()).sum(),
        current_noise,
        notes,
    })
}

/// The RMS equation error \[V\] and NRMSE fit \[%\] of the d and q voltages over the steady
/// samples, from the sums' squared errors `sse`.
fn goodness(logs: &[SteadyLog<'_>], sse: &[f64]) -> ([f64; 2], [f64; 2]) {
    let (mut n, mut s, mut s2) = (0.0f64, [0.0; 2], [0.0; 2]);
    for log in logs {
        let Ok((u_d, u_q)) = log.view.terminal_voltage() else { continue };
        for &k in &log.steady {
            n += 1.0;
            for (a, u) in [u_d[k], u_q[k]].into_iter().enumerate() {
                s[a] += u;
                s2[a] += u * u;
            }
        }
    }
    let rms = [0, 1].map(|a| (sse[a] / n.max(1.0)).sqrt());
    let fit = [0, 1].map(|a| {
        let spread = (s2[a] - s[a] * s[a] / n.max(1.0)).max(0.0);
        100.0 * (1.0 - (sse[a] / spread).sqrt())
    });
    (rms, fit)
}

/// The unit of parameter `name` of `kind` (`s^2` for the period term).
fn unit_of(kind: MotorKind, name: &str) -> &'static str {
    if name == PERIOD_TERM {
        return "s^2";
    }
    kind.parameter_names()
        .iter()
        .zip(kind.parameter_units())
        .find(|(n, _)| **n == name)
        .map_or("", |(_, u)| u)
}

/// The parameters the steady samples leave undetermined (relative standard error above
/// [`UNIDENTIFIABLE`]), each with what it would take.
fn notes(kind: MotorKind, names: &[String], theta: &[f64], se: &[f64]) -> Vec<String> {
    names
        .iter()
        .zip(theta.iter().zip(se))
        .filter(|(_, (t, s))| s.is_nan() || **s > UNIDENTIFIABLE * t.abs())
        .map(|(n, _)| format!("{n} not identifiable from these steady samples: {}", steady_advice(kind, n)))
        .collect()
}

/// What parameter `name` of `kind` needs at steady state (the advice of a poorly determined
/// parameter of a steady-state fit).
pub fn steady_advice(kind: MotorKind, name: &str) -> &'static str {
    match (kind, name.split('[').next().unwrap_or(name)) {
        (_, "r_s") => {
            "at steady state R_s is seen only through R_s i against the back-EMF; at high speed u ≫ R_s i: add steady samples at low speed and high current"
        }
        (MotorKind::Ipm, "l_d") => {
            "L_d enters only as ω_e L_d i_d: with i_d ≈ 0 it is not identifiable; add steady samples with d-current injection"
        }
        (MotorKind::Ipm, "l_q") | (MotorKind::Spm, "l_s") => {
            "L_q enters only as ω_e L_q i_q: it needs load current at speed"
        }
        (_, PERIOD_TERM | "h_c") => {
            "the control period shows only in the back-EMF's (ω_e h_c)²/12: it needs steady samples over a wide \
             range of speeds, or --control-period"
        }
        _ => "K_e needs steady samples at speed",
    }
}
