//! Running a solver on a [`LeastSquares`] problem through argmin's executor, as every fit
//! does: the solver chosen by [`SolverKind`], its report as a [`SolverReport`].

use super::SolverReport;
use super::gn::GaussNewton;
use super::lm::{DEFAULT_DAMPING, LevenbergMarquardt};
use super::trust::TrustRegion;
use super::{LeastSquares, LsState, ReportsTermination, Termination, Tolerances};
use crate::error::{Error, Result};
use argmin::core::observers::{Observe, ObserverMode};
use argmin::core::{Executor, Solver, State, TerminationReason};
use nalgebra::DVector;
use serde::{Deserialize, Serialize};
use std::sync::{Arc, Mutex, OnceLock};

/// Which optimiser runs the fit.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SolverKind {
    /// The trust region ([`TrustRegion`], on J's QR factors) where the problem keeps its
    /// Jacobian ([`LeastSquares::keeps_root`]: for a prediction-error problem, a static
    /// model with the quadratic loss, a dense `JᵀWJ` and at most
    /// [`ROOT_MAX_ENTRIES`](crate::estimate::ROOT_MAX_ENTRIES) numbers in J: a curve fit, a
    /// flux map, mechanics), Levenberg-Marquardt otherwise (a dynamic model's long record).
    /// MATLAB's `nlgreyestOptions` likewise defaults its search method to `'auto'`. On
    /// MINPACK's test set the trust region reaches MINPACK's sum of squares in no more
    /// evaluations than MINPACK on 50 of the 51 cases MINPACK solves, Levenberg-Marquardt
    /// on 12; on NIST StRD's 54 runs it solves 50, Levenberg-Marquardt 49 (the crate's
    /// `docs/performance.md`).
    #[default]
    Auto,
    /// Levenberg-Marquardt ([`LevenbergMarquardt`]).
    Lm,
    /// Damped Gauss-Newton with an Armijo backtracking line search ([`GaussNewton`]).
    Gn,
    /// Levenberg-Marquardt with MINPACK's trust region ([`TrustRegion`]; Moré 1978);
    /// `trust-region` in the command line, the JSON and the report.
    #[serde(rename = "trust-region")]
    TrustRegion,
}

/// How [`run_solver`] runs: the solver, its tolerances, and whether to report progress.
/// Plain data with defaults; serialisable.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RunOptions {
    /// The optimiser.
    pub solver: SolverKind,
    /// Stopping tolerances.
    pub tolerances: Tolerances,
    /// Report the run's iterations to the installed [`ProgressObserver`] (none installed:
    /// no effect).
    pub progress: bool,
    /// Levenberg-Marquardt's initial damping λ₀, relative to `diag(JᵀWJ)` (> 0; no effect
    /// on Gauss-Newton or the trust region, which starts from its radius Δ₀ instead).
    /// `None`: [`DEFAULT_DAMPING`]. Madsen, Nielsen & Tingleff (*Methods for non-linear
    /// least squares problems*, 2004, section 3.2) advise 1e-6 from a start
    /// believed close to the minimum and 1e-3 otherwise ([`CLOSE_START_DAMPING`]).
    pub initial_damping: Option<f64>,
    /// Levenberg-Marquardt's geodesic acceleration (Transtrum & Sethna 2012;
    /// [`LevenbergMarquardt::with_geodesic`]); off by default. No effect on Gauss-Newton or
    /// the trust region.
    pub geodesic: bool,
}

/// λ₀ of a run from a start believed close to the minimum, e.g. a linear least-squares
/// estimate on the same data (Madsen, Nielsen & Tingleff 2004, 3.2): the first steps are
/// nearly Gauss-Newton steps. A poor start costs a few rejected steps (λ doubles at each).
pub const CLOSE_START_DAMPING: f64 = 1e-6;

/// Runs the chosen solver from `p0` (length n_free) through argmin's executor; returns p̂
/// (the best point met) and the report. With n_free = 0 there is nothing to optimise: p̂ is
/// empty and the report says "all parameters fixed".
///
/// A run that stops without converging is not an error: [`SolverReport::success`] is
/// false and [`SolverReport::reason`] says why.
///
/// # Errors
/// [`Error::InvalidOption`] for invalid tolerances or an `initial_damping` that is not
/// positive and finite; those of [`LeastSquares::normal_equations`] at the start; every
/// error other than an unusable trial point during the run.
pub fn run_solver<O: LeastSquares>(
    problem: &O,
    p0: DVector<f64>,
    options: &RunOptions,
) -> Result<(DVector<f64>, SolverReport)> {
    options.tolerances.validate()?;
    if p0.is_empty() {
        return Ok((
            p0,
            SolverReport {
                name: "none".into(),
                iterations: 0,
                termination: "all parameters fixed".into(),
                reason: Termination::StepTolerance,
                success: true,
                evaluations: 0,
                accepted_iterations: 0,
                trace: Vec::new(),
            },
        ));
    }
    let solver = match options.solver {
        SolverKind::Auto if problem.keeps_root() => SolverKind::TrustRegion,
        SolverKind::Auto => SolverKind::Lm,
        chosen => chosen,
    };
    match solver {
        SolverKind::Auto | SolverKind::Lm => {
            let lm = LevenbergMarquardt::new(options.tolerances)
                .with_lambda(options.initial_damping.unwrap_or(DEFAULT_DAMPING))
                .map_err(|e| match e {
                    Error::InvalidOption { reason, .. } => {
                        Error::InvalidOption { option: "initial_damping".into(), reason }
                    }
                    other => other,
                })?
                .with_geodesic(options.geodesic);
            execute(problem, lm, p0, options)
        }
        SolverKind::Gn => execute(problem, GaussNewton::new(options.tolerances), p0, options),
        SolverKind::TrustRegion => execute(problem, TrustRegion::new(options.tolerances), p0, options),
    }
}

/// Runs `solver` from `p0` through argmin's executor and reports how it stopped.
fn execute<'p, O, S>(
    problem: &'p O,
    solver: S,
    p0: DVector<f64>,
    options: &RunOptions,
) -> Result<(DVector<f64>, SolverReport)>
where
    O: LeastSquares,
    S: Solver<&'p O, LsState> + ReportsTermination,
{
    let name = solver.name().to_string();
    let trace = Arc::new(Mutex::new(Vec::new()));
    let exec = Executor::new(problem, solver)
        .configure(|s| s.param(p0).max_iters(options.tolerances.max_iters).counting(true))
        .add_observer(Trace(Arc::clone(&trace)), ObserverMode::Always);
    let exec = match OBSERVER.get().filter(|_| options.progress) {
        Some(o) => exec.add_observer(Progress(o.as_ref()), ObserverMode::Always),
        None => exec,
    };
    let res = exec.run().map_err(Error::from_argmin)?;
    let counts = res.state.get_func_counts();
    let evaluations = ["normal_equations_count", "cost_count", super::geodesic::COUNT]
        .iter()
        .filter_map(|k| counts.get(*k))
        .sum();
    let reason = match (res.solver.termination(), res.state.get_termination_reason()) {
        (Some(t), _) => t.clone(),
        (None, Some(TerminationReason::MaxItersReached)) => Termination::MaxIterations,
        (None, r) => Termination::Stopped(r.map(|r| r.text().to_string()).unwrap_or_default()),
    };
    let p = res.state.get_best_param().cloned().ok_or_else(|| Error::Solver("no estimate".into()))?;
    Ok((
        p,
        SolverReport {
            name,
            iterations: res.state.get_iter(),
            termination: reason.to_string(),
            success: reason.success(),
            reason,
            evaluations,
            accepted_iterations: res.solver.accepted_iterations(),
            trace: std::mem::take(&mut *trace.lock().unwrap_or_else(|e| e.into_inner())),
        },
    ))
}

/// Records the solver's current point p at the start and after every iteration (one
/// vector of length n_free per entry: a few kilobytes for a fit, nothing beside its
/// simulations).
struct Trace(Arc<Mutex<Vec<Vec<f64>>>>);

impl Trace {
    fn record<I: State<Param = DVector<f64>>>(&self, state: &I) {
        if let Some(p) = state.get_param() {
            self.0.lock().unwrap_or_else(|e| e.into_inner()).push(p.as_slice().to_vec());
        }
    }
}

impl<I: State<Param = DVector<f64>>> Observe<I> for Trace {
    fn observe_init(
        &mut self,
        _name: &str,
        state: &I,
        _kv: &argmin::core::KV,
    ) -> std::result::Result<(), argmin::core::Error> {
        self.record(state);
        Ok(())
    }
    fn observe_iter(
        &mut self,
        state: &I,
        _kv: &argmin::core::KV,
    ) -> std::result::Result<(), argmin::core::Error> {
        self.record(state);
        Ok(())
    }
}

/// What a solver run reports as it goes, for a caller that shows it (the command line's
/// spinner): installed once per process with [`set_progress_observer`], called by every run
/// whose [`RunOptions::progress`] is set. The library itself shows nothing.
pub trait ProgressObserver: Send + Sync {
    /// After each iteration: the iterations done before it (argmin's counter, 0 after the
    /// first) and the best cost so far (units of the cost).
    fn iteration(&self, iteration: u64, cost: f64);
    /// The run has ended (converged, stopped, or failed).
    fn finished(&self);
}

/// The process's observer of solver runs, if one was installed.
static OBSERVER: OnceLock<Box<dyn ProgressObserver>> = OnceLock::new();

/// Installs the observer that runs with [`RunOptions::progress`] report to, once per
/// process; `false` (and `observer` dropped) when one was installed before.
pub fn set_progress_observer(observer: Box<dyn ProgressObserver>) -> bool {
    OBSERVER.set(observer).is_ok()
}

/// The argmin observer that forwards a run's iterations to the installed observer.
struct Progress(&'static dyn ProgressObserver);

impl<I: State<Float = f64>> Observe<I> for Progress {
    fn observe_iter(
        &mut self,
        state: &I,
        _kv: &argmin::core::KV,
    ) -> std::result::Result<(), argmin::core::Error> {
        self.0.iteration(state.get_iter(), state.get_best_cost());
        if state.terminated() {
            self.0.finished();
        }
        Ok(())
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.0.finished();
    }
}
