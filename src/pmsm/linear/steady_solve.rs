//! The instrumental-variable solution of the steady-state equations ([`super::steady`]):
//! the parameter layout (per-log parameters), the iteration over the small terms, and the
//! choice to estimate the control period's first-order effect (`h_c2`) or neglect it where
//! one speed cannot tell it from K_e.

use super::steady_model::{SteadyEquations, SteadyLog};
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::model::kind::MotorKind;
use serde::{Deserialize, Serialize};

/// Options of [`steady_state`](super::steady_state). Plain data with defaults; serialisable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SteadyOptions {
    /// A sample is steady when each current's second difference is at most this many
    /// `√6 σ_i` (σ_i the current's noise, estimated per experiment). Default 4: a smooth
    /// sample is rejected with probability ≈ 6e-5 per current.
    pub steady_sigmas: f64,
    /// Floor of the second difference allowed, as a fraction of the peak current (so
    /// \[A\] once multiplied by it), for noise-free logs (σ_i = 0). Default 1e-4.
    pub relative_floor: f64,
    /// The drive's control (PWM) period h_c \[s\], when known: the point-sampled currents
    /// are then related to the period-mean voltage exactly (the periodic steady state of
    /// the stator-held step, MODEL.md §4); `None`: the continuous equations with the
    /// period's first-order effect (a back-EMF low by `(ω_e h_c)²/12`) estimated as the
    /// nuisance parameter `h_c2 = h_c²`, or neglected where the steady samples' speeds
    /// cannot tell it from K_e (one speed).
    pub control_period: Option<f64>,
    /// Whether the period term `h_c2` is estimated when `control_period` is `None`
    /// (default `true`); `false`: the continuous equations alone, for logs whose drive
    /// is known to have no such effect (a voltage held in dq) or whose period a fit of
    /// more data has found to be none (the steady-state fit's parts, when the whole log's
    /// `h_c2` is not positive).
    pub estimate_period: bool,
    /// Parameters estimated per log (by name, e.g. `r_s` for a winding temperature per
    /// log), the others shared.
    pub per_experiment: Vec<String>,
    /// Known series (cable) resistance \[Ω\], taken out of `r_s`.
    pub cable_resistance: f64,
    /// Half width `a` of the currents' and the speed's central differences, in samples:
    /// `di/dt = (i[k+a] − i[k−a])/(2 a h)`, the instruments' means and slopes over
    /// `k ± (a + 1)`; from 1 to 4. Default 1.
    /// [`fit_pmsm`](crate::pmsm::fit_pmsm) fits with `a = 2` as well, whose truncation error
    /// is four times the default's, and widens the intervals by the difference
    /// (Richardson extrapolation).
    pub derivative_half_width: usize,
}

impl Default for SteadyOptions {
    fn default() -> Self {
        Self {
            steady_sigmas: 4.0,
            relative_floor: 1e-4,
            control_period: None,
            estimate_period: true,
            per_experiment: Vec::new(),
            cable_resistance: 0.0,
            derivative_half_width: 1,
        }
    }
}

/// The full parameter vector's names, logs and each log's columns: the model's parameters
/// in order, a per-log one once per log where it stands.
fn layout(
    model: &[&str],
    per: &[String],
    logs: &[String],
) -> (Vec<String>, Vec<Option<String>>, Vec<Vec<usize>>) {
    let (mut names, mut of) = (Vec::new(), Vec::new());
    let mut columns = vec![Vec::new(); logs.len()];
    for name in model {
        if per.iter().any(|p| p == name) {
            for (e, log) in logs.iter().enumerate() {
                columns[e].push(names.len());
                names.push((*name).to_string());
                of.push(Some(log.clone()));
            }
        } else {
            for c in &mut columns {
                c.push(names.len());
            }
            names.push((*name).to_string());
            of.push(None);
        }
    }
    (names, of, columns)
}

/// Most IV iterations (the small terms and the exact equations are nearly linear).
const MAX_ITERATIONS: usize = 20;

/// A step below this many standard errors of every parameter has converged too.
const STEP_IN_ERRORS: f64 = 1e-3;

/// Relative step below which the iteration has converged.
const STEP_TOLERANCE: f64 = 1e-12;

/// The nuisance parameter of the period's first-order effect (`h_c²` \[s²\]).
pub const PERIOD_TERM: &str = "h_c2";

/// |Correlation| of the K_e and `h_c2` estimates above which the period term is neglected:
/// K_e's standard error would grow by `1/√(1 − ρ²)`, over 700 times, so the steady samples
/// hold one speed to rounding. Below it the term is kept, however large K_e's interval
/// becomes: neglecting it leaves K_e low by `(ω_e h_c)²/12`, a bias no interval shows
/// (every 20th row of an independent noise-free 5 kHz IPM log of short moves, |ρ| 0.9973:
/// neglected at the former bound 0.995, K_e −0.124 % at |z| 8.6 and R_s +0.62 % at |z| 4.7
/// with exit 0; kept, K_e −0.003 % ± 0.005 % and `h_c` 1.98e-4 s against the drive's 2e-4).
const CONFOUNDED: f64 = 1.0 - 1e-6;

/// How the control period entered the equations.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Period {
    /// Given (`--control-period`): the exact equations.
    Given,
    /// Estimated as `h_c2`.
    Estimated,
    /// Neglected (one speed).
    Neglected,
    /// Not estimated, as the options asked ([`SteadyOptions::estimate_period`]).
    Off,
    /// Given, but not applied: the exact equations need a positive `r_s` and inductances,
    /// and the first estimate, the value here, had a parameter that is not.
    Unusable(String),
}

/// An IV solution of the steady samples.
pub(super) struct Solved {
    pub names: Vec<String>,
    pub experiment: Vec<Option<String>>,
    pub theta: Vec<f64>,
    pub cov: crate::estimate::iv::IvCovariance,
    pub sums: crate::estimate::iv::IvSums,
    pub iterations: usize,
    /// Whether the step fell below [`STEP_TOLERANCE`] before [`MAX_ITERATIONS`].
    pub converged: bool,
    pub period: Period,
}

impl Solved {
    /// Whether the period term was estimated but cannot be told from K_e.
    pub(super) fn period_confounded(&self, kind: MotorKind) -> bool {
        if self.period != Period::Estimated {
            return false;
        }
        let sd = |i: usize| self.cov.cov[(i, i)].max(0.0).sqrt();
        let (Some(k), Some(c)) = (
            self.names.iter().position(|n| n == "k_e" && kind.parameter_names().contains(&"k_e")),
            self.names.iter().position(|n| n == PERIOD_TERM),
        ) else {
            return false;
        };
        let rho = self.cov.cov[(k, c)] / (sd(k) * sd(c));
        !rho.is_finite() || rho.abs() > CONFOUNDED
    }
}

/// The IV solution of `logs` (their columns set here) with the period term estimated or
/// not: one step of the linear equations from zero, then steps with the small terms (and
/// a given control period's exact equations) at the previous estimate until the step is
/// below [`STEP_TOLERANCE`] (or a small fraction of every standard error); where the
/// estimated `h_c2`'s 95 % interval then lies above 0, on with the drifting currents'
/// period mean at that period held ([`SteadyEquations::drift`]) to convergence again.
///
/// # Errors
/// Those of [`SteadyEquations::sums`] and [`IvSums::step`](crate::estimate::iv::IvSums::step).
pub(super) fn solve(
    logs: &mut [SteadyLog<'_>],
    experiments: &[Experiment],
    n_p: u32,
    kind: MotorKind,
    options: &SteadyOptions,
    estimate: bool,
) -> Result<Solved> {
    let log_names: Vec<String> = experiments.iter().map(|e| e.name().to_string()).collect();
    let mut model: Vec<&str> = kind.parameter_names().to_vec();
    if estimate {
        model.push(PERIOD_TERM);
    }
    let (names, experiment, columns) = layout(&model, &options.per_experiment, &log_names);
    for (log, c) in logs.iter_mut().zip(columns) {
        log.columns = c;
    }
    let nth = names.len();
    let steady: usize = logs.iter().map(|l| l.steady.len()).sum();
    let block = (steady / (4 * crate::estimate::TARGET_BATCHES)).clamp(1, crate::model::BLOCK_LEN);
    // The first step from zero by the continuous equations (the exact ones need a motor).
    let mut eq = SteadyEquations::new(kind, n_p, options.cable_resistance, None, estimate)?
        .half_width(options.derivative_half_width);
    let mut theta = vec![0.0; nth];
    let mut iterations = 0;
    // The iteration's first stage without the drifting currents' period mean (its term is
    // first order in h_c = √h_c2, whose slope at h_c2 = 0 has no bound: the fixed point
    // would not contract near it); the second, where the first found a period, with that
    // period's drift held.
    let period_column = names.iter().position(|n| n == PERIOD_TERM);
    let (mut stage, mut drift) = (0, false);
    let mut unusable = None;
    // The sums at the current θ (and their covariance once formed): each pass over the
    // steady samples serves the convergence test, the next step and the result alike.
    let mut sums = eq.sums(logs, &theta, block)?;
    let mut cov = None;
    let converged = loop {
        let step = sums.step()?;
        theta.iter_mut().zip(step.iter()).for_each(|(t, s)| *t += s);
        iterations += 1;
        if iterations == 1 && !estimate && options.control_period.is_some() {
            let mut exact =
                SteadyEquations::new(kind, n_p, options.cable_resistance, options.control_period, false)?
                    .half_width(options.derivative_half_width);
            // The exact equations at a non-physical first estimate (a log that does not
            // determine r_s): the equations without the period carry on, and the report's
            // gate names the estimate, as it does without --control-period.
            match exact.sums(logs, &theta, block) {
                Ok(at) => {
                    (eq, sums) = (exact, at);
                    continue;
                }
                Err(Error::InvalidParameter { name, value, .. }) => {
                    unusable = Some(format!("{name} = {value:.4e}"))
                }
                Err(e) => return Err(e),
            }
        }
        sums = eq.sums(logs, &theta, block)?;
        let rounding =
            step.iter().zip(&theta).all(|(s, t)| s.abs() <= STEP_TOLERANCE * t.abs().max(f64::MIN_POSITIVE));
        // Or a step within a small fraction of every standard error: converged for every
        // purpose the interval serves (a short log's poorly determined period term makes
        // the fixed point contract slowly near h_c2 = 0).
        let small = rounding || {
            let c = sums.covariance()?;
            let small = step
                .iter()
                .enumerate()
                .all(|(j, s)| s.abs() <= STEP_IN_ERRORS * c.cov[(j, j)].max(0.0).sqrt());
            cov = Some(c);
            small
        };
        if small || iterations >= stage + MAX_ITERATIONS {
            // A period the first stage found (h_c2's 95 % interval above 0): its drift
            // held from here on.
            if let (false, Some(c)) = (drift, period_column) {
                let v = match cov.take() {
                    Some(v) => v,
                    None => sums.covariance()?,
                };
                let found = theta[c] > v.t_quantile() * v.cov[(c, c)].max(0.0).sqrt();
                (cov, drift) = (Some(v), true);
                if found {
                    eq = eq.drift(theta[c].sqrt());
                    (stage, cov) = (iterations, None);
                    sums = eq.sums(logs, &theta, block)?;
                    continue;
                }
            }
            break small;
        }
        cov = None;
    };
    let cov = match cov {
        Some(c) => c,
        None => sums.covariance()?,
    };
    let period = match (estimate, options.control_period) {
        _ if let Some(what) = unusable => Period::Unusable(what),
        (true, _) => Period::Estimated,
        (false, Some(_)) => Period::Given,
        (false, None) if !options.estimate_period => Period::Off,
        (false, None) => Period::Neglected,
    };
    Ok(Solved { names, experiment, theta, cov, sums, iterations, converged, period })
}

/// The note of the period term: the control period estimated, or why it was neglected.
pub(super) fn period_note(period: Period, names: &[String], theta: &[f64], se: &[f64]) -> Option<String> {
    match period {
        Period::Given => None,
        Period::Unusable(what) => Some(format!(
            "the control period given (--control-period) is not applied: its exact equations need a positive \
             r_s and inductances, and the equations' first estimate has {what}; the estimates are those of the \
             equations without it"
        )),
        Period::Off => Some(
            "the control period's effect on the point-sampled currents (a back-EMF low by (ω_e h_c)²/12) is not \
             estimated, as the options ask (estimate_period false)"
                .to_string(),
        ),
        Period::Neglected => Some(
            "the control period's effect on the point-sampled currents (a back-EMF low by (ω_e h_c)²/12) is not \
             estimated: the steady samples hold about one speed, where it cannot be told from K_e; give \
             --control-period (K_e then exact)"
                .to_string(),
        ),
        Period::Estimated => {
            let c = names.iter().position(|n| n == PERIOD_TERM)?;
            let h_c = theta[c].max(0.0).sqrt();
            Some(format!(
                "the drive's control period from the back-EMF's (ω_e h_c)²/12 (the stator-held voltage turns in dq \
                 over a period): h_c2 = {:.3e} ± {:.1e} s², h_c ≈ {h_c:.3e} s; --control-period gives it instead",
                theta[c], se[c]
            ))
        }
    }
}
