//! Estimation: the prediction-error fit of any [`GreyBoxModel`], weighted linear least
//! squares, parameter scaling and the solvers.
//!
//! [`fit`] is the generic entry point: it builds a [`PemProblem`] over one or more
//! experiments, runs the chosen argmin solver from a given start and computes the
//! statistics of the estimate. Domain workflows (e.g. [`crate::pmsm::fit_pmsm`]) build on
//! it.

// The submodules are the crate's; their public items are re-exported here, one path each.
pub(crate) mod arrowhead;
pub(crate) mod assemble;
pub(crate) mod colour;
pub(crate) mod consistency;
pub(crate) mod correction;
mod covariance;
pub(crate) mod design;
pub(crate) mod diagnostics;
pub(crate) mod filter;
pub(crate) mod gate;
pub(crate) mod iv;
mod jackknife;
pub(crate) mod linear;
pub(crate) mod metrics;
mod options;
mod paired;
pub(crate) mod precision;
pub(crate) mod problem;
mod quantile;
pub(crate) mod restricted;
pub(crate) mod result;
pub(crate) mod scaling;
pub(crate) mod solver;
pub(crate) mod spline;
#[cfg(test)]
pub(crate) mod test_rng;
pub(crate) mod weighting;

pub use arrowhead::{
    ArrowInverse, ArrowLayout, Arrowhead, LowRank, Sandwich, Singular, SolveTiming, solve_timing,
};
pub use assemble::AT_BOUND;
pub use colour::STRONG_COLOUR;
pub use consistency::{
    Homogeneity, PARTS, PARTS_FLOOR, PARTS_LEVEL, Refit, between_variance, chi_square_sf, consecutive_parts,
    disagreeing, disagreement, disagreement_of, homogeneity, homogeneity_where_estimated, static_parts,
    widened_by_parts,
};
pub use correction::CriterionCorrection;
pub use design::{
    Candidate, Criterion, DesignOptions, PredictedParameter, Prediction, SearchOutcome, Target, predict,
    search_shortest,
};
pub use diagnostics::{Correlated, DiagnosticThresholds, Diagnostics, PoorlyDetermined, diagnose};
pub use filter::{Biquad, Butterworth, DEFAULT_ORDER, MAX_ORDER, PAD_TIME_CONSTANTS, check_order};
pub use gate::{POOR_FIT_PERCENT, SINGULAR_CONDITION, STATIONARY_STEP, STEP_ROUNDING};
pub use iv::{IvCovariance, IvSums, one_step_sums};
pub use linear::{BLOCK, LinearSolution, RANK_TOLERANCE, StreamedLeastSquares, solve_weighted};
pub use metrics::{Metrics, Whiteness, aic, bic, fit_percent, fpe, metrics, whiteness, whiteness_of};
pub use options::PemOptions;
pub(crate) use paired::paired_difference_variance;
pub use precision::{PRECISION_Z, PrecisionTarget, imprecise};
#[cfg(test)]
pub(crate) use problem::lagged_dots;
pub use problem::{
    BatchMeans, FreeKind, FreeParameter, LAG_CHUNK, LagSums, Loss, MIN_BATCHES, OUTPUT_WEIGHT_RANGE,
    PemProblem, ProblemOptions, ROOT_MAX_ENTRIES, STRUCTURED_ABOVE, Slot, Sums, TARGET_BATCHES, Term,
    WHITENESS_LAGS, WeightedData,
};
pub use quantile::{interval_quantile, t_quantile_975};
pub use result::{
    CovarianceMethod, FitResult, FitStatistics, ParameterEstimate, Timing, Uncertainty, Warning,
};
pub use scaling::{
    ColumnNormScaling, IdentityScaling, LogScaling, NominalScaling, ParameterScaling, ScalingKind, Transform,
};
pub use solver::gn::GaussNewton;
pub use solver::lm::{DEFAULT_DAMPING, LevenbergMarquardt};
pub use solver::run::{
    CLOSE_START_DAMPING, ProgressObserver, RunOptions, SolverKind, run_solver, set_progress_observer,
};
pub use solver::trust::TrustRegion;
pub use solver::{
    Gram, LeastSquares, LsState, NormalEquations, ReportsTermination, Root, SolverReport, Termination,
    Tolerances,
};
pub use spline::{SPLINE_INTERVALS, SplineSurface};
pub use weighting::{
    CustomWeighting, SampleWeightFn, SpeedShape, SpeedWeighting, Uniform, Weighting, WeightingKind,
};

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Prepared};
use assemble::assemble;
use std::time::Instant;

/// Prediction-error fit of `model` to `experiments` from `start` (length n_θ, model order).
///
/// # Errors
/// Those of [`GreyBoxModel::prepare`]; [`Error::InvalidOption`], [`Error::InvalidBounds`],
/// [`Error::StartOutsideBounds`] for inconsistent options (see [`PemProblem::new`]);
/// [`Error::SimulationDiverged`] or [`Error::InvalidParameter`] when the model cannot be
/// simulated at the start. A fit that stops without converging is not an error: its
/// [`SolverReport::success`] is false.
///
/// # Example
/// ```no_run
/// use greybox::{estimate, pmsm::{PmsmSpm, VoltageHold}};
/// # fn main() -> greybox::Result<()> {
/// let log = greybox::pmsm::read_log("data/sample.csv.gz", &Default::default())?;
/// let model = PmsmSpm::new(4, VoltageHold::Stator);
/// let fit = estimate::fit(&model, &[log], &[1.0, 5e-3, 0.5], &Default::default())?;
/// println!("{fit}");
/// # Ok(()) }
/// ```
pub fn fit<M: GreyBoxModel>(
    model: &M,
    experiments: &[Experiment],
    start: &[f64],
    options: &PemOptions,
) -> Result<FitResult> {
    let rule = options.weighting.rule()?;
    fit_with_weighting(model, experiments, start, options, rule.as_ref())
}

/// As [`fit`], with a weighting rule object (e.g. a [`weighting::CustomWeighting`]) in place of
/// `options.weighting`. `options.output_weights`, when set, override the rule's.
///
/// # Errors
/// As [`fit`]; [`Error::InvalidOption`] for negative or non-finite weights.
pub fn fit_with_weighting<M: GreyBoxModel>(
    model: &M,
    experiments: &[Experiment],
    start: &[f64],
    options: &PemOptions,
    weighting: &dyn Weighting,
) -> Result<FitResult> {
    let t0 = Instant::now();
    let (problem, popts) = build_problem(model, experiments, start, options, weighting)?;
    let parts = |theta: &[f64]| {
        consistency::static_parts(experiments, theta, &|part, at| {
            let (problem, popts) = build_problem(model, part, at, options, weighting)?;
            finish(problem, popts, at, options, weighting, Clock::from(Instant::now()), None)
        })
    };
    finish(problem, popts, start, options, weighting, Clock::from(t0), Some(&parts))
}

/// Runs the solver on `problem` from `start` and assembles the result (the Huber refit
/// included): the common end of [`fit_with_weighting`] and [`StartedFit::fit`]. `parts`:
/// a static model's self-consistency check ([`consistency::static_parts`]), which the gate
/// consults on a poor fit in place of the residuals' whiteness along the data's order.
fn finish<M: GreyBoxModel>(
    problem: PemProblem<'_, M>,
    mut popts: ProblemOptions,
    start: &[f64],
    options: &PemOptions,
    weighting: &dyn Weighting,
    clock: Clock,
    parts: Option<&assemble::PartsCheck<'_>>,
) -> Result<FitResult> {
    let model = problem.model();
    let uniform = weighting.is_uniform();
    let scaling = options.scaling.rule();
    let p0 = problem.start_vector(start);
    let solve_t0 = Instant::now();
    let (mut p_hat, mut report) = solve(&problem, p0, options, weighting)?;
    let mut solve_s = clock.solved_s + solve_t0.elapsed().as_secs_f64();
    let mut notes = Vec::new();
    let problem = match options.huber {
        None => problem,
        Some(c) => {
            // Thresholds from the robust scale of the quadratic fit's residuals, then the
            // Huber fit from the quadratic estimate.
            let scale = problem.robust_scale(&p_hat)?;
            let delta: Vec<f64> = scale.iter().map(|s| c * s.max(f64::MIN_POSITIVE)).collect();
            notes.push(format!(
                "Huber loss, thresholds {} (c = {c} × 1.4826 MAD of the quadratic fit's residuals)",
                delta.iter().map(|d| format!("{d:.4e}")).collect::<Vec<_>>().join(", ")
            ));
            // Restart from the whole fitted vector: every per-experiment copy and every
            // estimated initial state, not only experiment 0's parameters.
            let values = problem.free_values(&p_hat);
            let trace_values: Vec<Vec<f64>> = std::mem::take(&mut report.trace)
                .into_iter()
                .map(|q| problem.free_values(&nalgebra::DVector::from_vec(q)))
                .collect();
            let terms = problem.into_data();
            popts.loss = Loss::Huber { delta };
            let robust = PemProblem::new(model, terms, start, scaling.as_ref(), &popts)?;
            let p1 = robust.point_from_values(&values);
            // The quadratic run's trace, in the robust problem's scaled space, before its own.
            let mut trace: Vec<Vec<f64>> =
                trace_values.iter().map(|v| robust.point_from_values(v).as_slice().to_vec()).collect();
            let robust_t0 = Instant::now();
            (p_hat, report) = solve(&robust, p1, options, weighting)?;
            solve_s += robust_t0.elapsed().as_secs_f64();
            trace.append(&mut report.trace);
            report.trace = trace;
            robust
        }
    };
    let mut result = assemble(
        &problem,
        &p_hat,
        start,
        report,
        &options.diagnostics,
        parts,
        weighting.criterion_correction(),
    )?;
    result.notes.append(&mut notes);
    if !uniform {
        result.notes.push(format!("sample weighting: {}", weighting.name()));
    }
    result.timing.fit_s = clock.t0.elapsed().as_secs_f64();
    result.timing.total_s = result.timing.fit_s;
    result.timing.solve_s = Some(solve_s);
    Ok(result)
}

/// Runs the solver on `problem` from `p0`, its criterion compensated by the weighting's
/// [`CriterionCorrection`] if it has one.
fn solve<M: GreyBoxModel>(
    problem: &PemProblem<'_, M>,
    p0: nalgebra::DVector<f64>,
    options: &PemOptions,
    weighting: &dyn Weighting,
) -> Result<(nalgebra::DVector<f64>, SolverReport)> {
    match weighting.criterion_correction() {
        Some(correction) => {
            run_solver(&correction::Compensated { problem, correction }, p0, &options.run_options())
        }
        None => run_solver(problem, p0, &options.run_options()),
    }
}

/// The prediction-error problem of a fit: the experiments prepared, their weights, the
/// options (shared by [`fit_with_weighting`] and [`predicted_loss`]).
fn build_problem<'m, M: GreyBoxModel>(
    model: &'m M,
    experiments: &[Experiment],
    start: &[f64],
    options: &PemOptions,
    weighting: &dyn Weighting,
) -> Result<(PemProblem<'m, M>, ProblemOptions)> {
    options.tolerances.validate()?;
    let uniform = weighting.is_uniform();
    let preps = experiments
        .iter()
        .map(|e| Ok((Prepared::new(model, e)?, if uniform { None } else { Some(weighting.weights(e)?) })))
        .collect::<Result<Vec<_>>>()?;
    if let Some(c) = options.huber
        && !(c.is_finite() && c > 0.0)
    {
        return Err(Error::InvalidOption {
            option: "huber".into(),
            reason: format!("constant must be positive, got {c}"),
        });
    }
    let scaling = options.scaling.rule();
    let popts = ProblemOptions {
        per_experiment: options.per_experiment.clone(),
        horizon: options.horizon,
        output_weights: options.output_weights.clone().or_else(|| weighting.output_weights()),
        loss: Loss::Quadratic,
        estimate_x0: options.estimate_x0,
        structured_above: options.structured_above,
        prefilters: match options.prefilter {
            None => Vec::new(),
            Some(fc) => experiments
                .iter()
                .map(|e| {
                    filter::Butterworth::try_new(filter::DEFAULT_ORDER, fc, e.h()).map_err(|err| match err {
                        Error::InvalidOption { reason, .. } => Error::InvalidOption {
                            option: "prefilter".into(),
                            reason: format!("{reason} (experiment `{}`)", e.name()),
                        },
                        other => other,
                    })
                })
                .collect::<Result<_>>()?,
        },
    };
    let problem = PemProblem::new(model, preps, start, scaling.as_ref(), &popts)?;
    Ok((problem, popts))
}

/// A fit built and evaluated at its start, not yet run: the prepared experiments and one
/// normal-equation pass at the start, from which [`predicted_loss`](Self::predicted_loss)
/// comes and with which [`fit`](Self::fit) begins (the pass is not repeated; the estimate
/// is the same bits as [`fit_with_weighting`]'s).
pub struct StartedFit<'m, M: GreyBoxModel> {
    problem: PemProblem<'m, M>,
    popts: ProblemOptions,
    options: PemOptions,
    weighting: &'m dyn Weighting,
    start: Vec<f64>,
    predicted: f64,
    clock: Clock,
}

/// When a fit began, and the solver's time already spent before [`finish`] (the pass at
/// the start that [`StartedFit`] makes and the solver then takes as its first) \[s\].
struct Clock {
    t0: Instant,
    solved_s: f64,
}

impl From<Instant> for Clock {
    fn from(t0: Instant) -> Self {
        Self { t0, solved_s: 0.0 }
    }
}

impl<'m, M: GreyBoxModel> StartedFit<'m, M> {
    /// Builds the fit of `model` to `experiments` from `start` (length n_θ, model order) and
    /// makes its normal-equation pass at the start.
    ///
    /// # Errors
    /// As [`fit_with_weighting`] at the start.
    pub fn new(
        model: &'m M,
        experiments: &[Experiment],
        start: &[f64],
        options: &PemOptions,
        weighting: &'m dyn Weighting,
    ) -> Result<Self> {
        let t0 = Instant::now();
        let (problem, popts) = build_problem(model, experiments, start, options, weighting)?;
        let seed_t0 = Instant::now();
        let ne = problem.seeded_normal_equations(&problem.start_vector(start))?;
        let clock = Clock { t0, solved_s: seed_t0.elapsed().as_secs_f64() };
        let drop = ne.jtj.solve(&ne.jtr).map(|x| 0.5 * ne.jtr.dot(&x)).unwrap_or(0.0);
        let predicted = (ne.cost - drop).max(0.0);
        Ok(Self {
            problem,
            popts,
            options: options.clone(),
            weighting,
            start: start.to_vec(),
            predicted,
            clock,
        })
    }

    /// The loss that the fit is predicted to reach, from the pass at the start: the
    /// Gauss-Newton minimum of the local quadratic model, `V − ½ gᵀH⁻¹g` with `g = JᵀWε`,
    /// `H = JᵀWJ` (Nocedal & Wright, *Numerical Optimization*, 2nd ed., 10.3), floored at
    /// 0; `V` itself when `H` is singular (units of the cost).
    pub fn predicted_loss(&self) -> f64 {
        self.predicted
    }

    /// The start it was built from (length n_θ, model order).
    pub fn start(&self) -> &[f64] {
        &self.start
    }

    /// Runs the fit: as [`fit_with_weighting`] with the options and weighting it was built
    /// with.
    ///
    /// # Errors
    /// As [`fit_with_weighting`].
    pub fn fit(self) -> Result<FitResult> {
        finish(self.problem, self.popts, &self.start, &self.options, self.weighting, self.clock, None)
    }
}

/// The loss that a fit of `model` from `start` is predicted to reach, from one
/// normal-equation pass at the start ([`StartedFit::predicted_loss`]). Cheap evidence for
/// a choice between model structures (e.g. two voltage holds) before fitting only the
/// better one; [`StartedFit`] keeps the pass for that fit.
///
/// # Errors
/// As [`fit_with_weighting`] at the start.
pub fn predicted_loss<M: GreyBoxModel>(
    model: &M,
    experiments: &[Experiment],
    start: &[f64],
    options: &PemOptions,
    weighting: &dyn Weighting,
) -> Result<f64> {
    StartedFit::new(model, experiments, start, options, weighting).map(|s| s.predicted_loss())
}
