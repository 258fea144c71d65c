//! The instrumental-variable solution of the steady-state equations ([`super::steady`]):
//! the parameter layout (per-log parameters), the iteration over the small terms, and the
//! choice to estimate the control period's first-order effect (`h_c2`) or neglect it where
//! one speed cannot tell it from K_e.

use super::steady::SteadyOptions;
use super::steady_model::{SteadyEquations, SteadyLog};
use crate::data::Experiment;
use crate::error::Result;
use crate::pmsm::model::kind::MotorKind;

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

/// Relative step below which the iteration has converged.
const STEP_TOLERANCE: f64 = 1e-12;

/// The nuisance parameter of the period's first-order effect (`h_c²` \[s²\]).
pub const PERIOD_TERM: &str = "h_c2";

/// |Correlation| of the K_e and `h_c2` estimates above which the period term is neglected
/// (K_e's standard error would grow tenfold: the steady samples hold about one speed).
const CONFOUNDED: f64 = 0.995;

/// How the control period entered the equations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Period {
    /// Given (`--control-period`): the exact equations.
    Given,
    /// Estimated as `h_c2`.
    Estimated,
    /// Neglected (one speed).
    Neglected,
}

/// An IV solution of the steady samples.
pub(super) struct Solved {
    pub names: Vec<String>,
    pub experiment: Vec<Option<String>>,
    pub theta: Vec<f64>,
    pub cov: crate::estimate::iv::IvCovariance,
    pub sums: crate::estimate::iv::IvSums,
    pub iterations: usize,
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
/// below [`STEP_TOLERANCE`].
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
    let mut eq = SteadyEquations::new(kind, n_p, options.cable_resistance, None, estimate)?;
    let mut theta = vec![0.0; nth];
    let mut iterations = 0;
    loop {
        let step = eq.sums(logs, &theta, block)?.step()?;
        theta.iter_mut().zip(step.iter()).for_each(|(t, s)| *t += s);
        iterations += 1;
        if iterations == 1 && !estimate && options.control_period.is_some() {
            eq = SteadyEquations::new(kind, n_p, options.cable_resistance, options.control_period, false)?;
            continue;
        }
        let small =
            step.iter().zip(&theta).all(|(s, t)| s.abs() <= STEP_TOLERANCE * t.abs().max(f64::MIN_POSITIVE));
        if small || iterations >= MAX_ITERATIONS {
            break;
        }
    }
    let sums = eq.sums(logs, &theta, block)?;
    let cov = sums.covariance()?;
    let period = match (estimate, options.control_period) {
        (true, _) => Period::Estimated,
        (false, Some(_)) => Period::Given,
        (false, None) => Period::Neglected,
    };
    Ok(Solved { names, experiment, theta, cov, sums, iterations, period })
}

/// The note of the period term: the control period estimated, or why it was neglected.
pub(super) fn period_note(period: Period, names: &[String], theta: &[f64], se: &[f64]) -> Option<String> {
    match period {
        Period::Given => None,
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
