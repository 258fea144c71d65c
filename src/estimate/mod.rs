//! Estimation: the prediction-error fit of any [`GreyBoxModel`], weighted linear least
//! squares, parameter scaling and the solvers.
//!
//! [`fit`] is the generic entry point: it builds a [`PemProblem`] over one or more
//! experiments, runs the chosen argmin solver from a given start and computes the
//! statistics of the estimate. Domain workflows (e.g. [`crate::pmsm::fit_pmsm`]) build on
//! it.

pub mod diagnostics;
pub mod filter;
pub mod linear;
pub mod problem;
pub mod result;
pub mod scaling;
pub mod solver;
pub mod weighting;

pub use problem::{Loss, PemProblem, ProblemOptions};
pub use result::{DerivedEstimate, FitResult, FitStatistics, ParameterEstimate, SolverReport, Timing};
pub use scaling::{ParameterScaling, ScalingKind, Transform};
pub use solver::gn::{self, GaussNewton};
pub use solver::lm::{self, LevenbergMarquardt};
pub use solver::run::{RunOptions, SolverKind, run_solver};
pub use solver::{LeastSquares, LsState, NormalEquations, ReportsTermination, Termination, Tolerances};
pub use weighting::{Weighting, WeightingKind};

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Prepared};
use diagnostics::{DiagnosticThresholds, diagnose};
use nalgebra::{DMatrix, DVector};
use problem::FreeKind;
use result::t_quantile_975;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Options of a prediction-error fit. Plain data with defaults; serialisable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PemOptions {
    /// The optimiser.
    pub solver: SolverKind,
    /// Stopping tolerances.
    pub tolerances: Tolerances,
    /// Parameter scaling rule.
    pub scaling: ScalingKind,
    /// k-step-ahead prediction horizon; `None` = output error (simulation).
    pub horizon: Option<usize>,
    /// Parameters estimated separately for every experiment (e.g. `["r_s"]`).
    pub per_experiment: Vec<String>,
    /// Output weights Λ (length n_y), `None` = 1 (or the weighting rule's).
    pub output_weights: Option<Vec<f64>>,
    /// Sample weighting β_k (thesis eq. 5.11); a custom rule goes through [`fit_with_weighting`].
    pub weighting: WeightingKind,
    /// Robust fit: Huber loss with threshold `δ_i = c σ̂_i` per output, where `c` is this
    /// value (1.345 is the usual choice: 95 % efficiency under Gaussian noise) and σ̂_i the
    /// robust scale `1.4826 MAD` of the residuals of a preceding quadratic fit. `None` =
    /// quadratic loss.
    pub huber: Option<f64>,
    /// Residual prefilter L(q): cutoff [Hz] of a causal low-pass Butterworth filter of
    /// order 4 applied to the residuals and their sensitivities (the thesis uses a
    /// 4th-order low-pass; MODEL.md §5). `None` = no filter.
    pub prefilter: Option<f64>,
    /// Estimate each experiment's initial state (n_x nuisance parameters per experiment)
    /// instead of taking the first measurement as exact. On by default: noise on the first
    /// sample otherwise propagates through the first time constants of every residual and
    /// the reported intervals come out too narrow on short noisy records.
    pub estimate_x0: bool,
    /// Thresholds of the identifiability diagnostics.
    pub diagnostics: DiagnosticThresholds,
    /// Show a progress spinner on stderr (only when stderr is a terminal). Has an effect
    /// only with the `cli` feature (which brings in `indicatif`); ignored without it.
    pub progress: bool,
}

impl PemOptions {
    /// The options of the solver run.
    pub fn run_options(&self) -> RunOptions {
        RunOptions { solver: self.solver, tolerances: self.tolerances, progress: self.progress }
    }
}

impl Default for PemOptions {
    fn default() -> Self {
        Self {
            solver: SolverKind::Lm,
            tolerances: Tolerances::default(),
            scaling: ScalingKind::Nominal,
            horizon: None,
            per_experiment: Vec::new(),
            output_weights: None,
            weighting: WeightingKind::Uniform,
            huber: None,
            prefilter: None,
            estimate_x0: true,
            diagnostics: DiagnosticThresholds::default(),
            progress: false,
        }
    }
}

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
    let mut popts = ProblemOptions {
        per_experiment: options.per_experiment.clone(),
        horizon: options.horizon,
        output_weights: options.output_weights.clone().or_else(|| weighting.output_weights()),
        loss: Loss::Quadratic,
        estimate_x0: options.estimate_x0,
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
    let p0 = problem.start_vector(start);
    let (mut p_hat, mut report) = run_solver(&problem, p0, &options.run_options())?;
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
            let terms = problem.into_data();
            popts.loss = Loss::Huber { delta };
            let robust = PemProblem::new(model, terms, start, scaling.as_ref(), &popts)?;
            let p1 = robust.point_from_values(&values);
            (p_hat, report) = run_solver(&robust, p1, &options.run_options())?;
            robust
        }
    };
    let mut result = assemble(&problem, &p_hat, start, report, &options.diagnostics)?;
    result.notes.append(&mut notes);
    if !uniform {
        result.notes.push(format!("sample weighting: {}", weighting.name()));
    }
    result.timing.fit_s = t0.elapsed().as_secs_f64();
    result.timing.total_s = result.timing.fit_s;
    Ok(result)
}

/// Computes the statistics at p̂ and fills a [`FitResult`].
pub(crate) fn assemble<M: GreyBoxModel>(
    problem: &PemProblem<'_, M>,
    p: &DVector<f64>,
    start: &[f64],
    solver: SolverReport,
    thresholds: &DiagnosticThresholds,
) -> Result<FitResult> {
    let model = problem.model();
    let params = model.parameters();
    let (ny, np) = (model.n_outputs(), problem.n_free());
    let sums = problem.sums(p)?;
    let n = sums.count;
    let n_res = n * ny;
    let dof = n_res.saturating_sub(np);
    let sse_total: f64 = sums.sse.iter().sum();
    // Inverses for the reported covariance and error index (the one explicit inverse,
    // STYLE.md rule 7): bread⁻¹ meat bread⁻¹ (sandwich) and (JᵀWJ)⁻¹.
    // Parameters the data do not see at all (a zero column, e.g. an initial state whose
    // transient is weighted out) are left out of the inversion and get an infinite error.
    let info_inv = inverse_on_support(&sums.jtj);
    let bread_inv = inverse_on_support(&sums.bread);
    let dtheta: Vec<f64> =
        problem.free().iter().enumerate().map(|(g, f)| f.transform.dtheta_dp(p[g])).collect();
    let cov_theta = bread_inv.as_ref().map(|ai| {
        let cov_p = ai * &sums.meat * ai;
        DMatrix::from_fn(np, np, |i, j| cov_p[(i, j)] * dtheta[i] * dtheta[j])
    });
    let tq = t_quantile_975(dof);
    let names = problem.terms().iter().map(|t| t.prep.name.clone()).collect::<Vec<_>>();
    let states = model.states();
    let estimate = |g: usize, name: String, unit: String, start: f64| {
        let f = &problem.free()[g];
        let value = f.transform.to_theta(p[g]);
        let unseen = sums.bread[(g, g)].is_nan() || sums.bread[(g, g)] <= 0.0;
        let se = match &cov_theta {
            Some(c) if !unseen => c[(g, g)].max(0.0).sqrt(),
            _ => f64::INFINITY,
        };
        let idx = info_inv.as_ref().map_or(f64::INFINITY, |ai| {
            100.0 * (sums.e2_weighted * ai[(g, g)]).max(0.0).sqrt() * dtheta[g].abs() / value.abs()
        });
        ParameterEstimate {
            name,
            unit,
            value,
            std_error: se,
            ci95: [value - tq * se, value + tq * se],
            error_index_percent: idx,
            fixed: false,
            experiment: f.experiment.map(|e| names[e].clone()),
            start,
        }
    };
    let mut parameters = Vec::new();
    // Free entries of `parameters`, in order, are the free indices in `order`.
    let mut order = Vec::new();
    for (j, prm) in params.iter().enumerate() {
        let copies: Vec<usize> =
            (0..np).filter(|&g| problem.free()[g].kind == FreeKind::Parameter(j)).collect();
        if copies.is_empty() {
            parameters.push(ParameterEstimate {
                name: prm.name.clone(),
                unit: prm.unit.clone(),
                value: start[j],
                std_error: 0.0,
                ci95: [start[j], start[j]],
                error_index_percent: 0.0,
                fixed: true,
                experiment: None,
                start: start[j],
            });
        }
        for g in copies {
            parameters.push(estimate(g, prm.name.clone(), prm.unit.clone(), start[j]));
            order.push(g);
        }
    }
    let mut initial_states = Vec::new();
    for (g, f) in problem.free().iter().enumerate() {
        if let (FreeKind::InitialState(i), Some(e)) = (f.kind, f.experiment) {
            let x0 = problem.terms()[e].prep.x0[i];
            let s = &states[i];
            initial_states.push(estimate(g, format!("x0_{}", s.name), s.unit.clone(), x0));
        }
    }
    let correlation = match &cov_theta {
        Some(c) => order
            .iter()
            .map(|&a| order.iter().map(|&b| c[(a, b)] / (c[(a, a)] * c[(b, b)]).sqrt()).collect())
            .collect(),
        None => vec![vec![f64::NAN; order.len()]; order.len()],
    };
    let diag_names: Vec<String> = order
        .iter()
        .map(|&g| {
            let f = &problem.free()[g];
            let FreeKind::Parameter(j) = f.kind else { unreachable!("order holds model parameters only") };
            match f.experiment {
                Some(e) => format!("{}[{}]", params[j].name, names[e]),
                None => params[j].name.clone(),
            }
        })
        .collect();
    let rel = |g: usize| problem.free()[g].transform.to_theta(p[g]) / dtheta[g];
    let info_rel = DMatrix::from_fn(order.len(), order.len(), |a, b| {
        let (ga, gb) = (order[a], order[b]);
        sums.jtj[(ga, gb)] * rel(ga) * rel(gb)
    });
    let free_index: Vec<f64> =
        parameters.iter().filter(|q| !q.fixed).map(|q| q.error_index_percent).collect();
    let diagnostics = diagnose(
        &info_rel,
        &diag_names,
        &free_index,
        &correlation,
        thresholds,
        &|n| model.advice(n),
        &|a, b| model.pair_advice(a, b),
    );
    let fit = FitStatistics {
        outputs: model.outputs().into_iter().map(|o| o.name).collect(),
        fit_percent: sums
            .sse
            .iter()
            .zip(&sums.sst)
            .map(|(e, t)| if *t > 0.0 { 100.0 * (1.0 - (e / t).sqrt()) } else { f64::NAN })
            .collect(),
        rms_residual: sums.sse.iter().map(|e| (e / n as f64).sqrt()).collect(),
        loss: sums.cost,
        mse: sse_total / n_res as f64,
        aic: n_res as f64 * (sse_total / n_res as f64).ln() + 2.0 * np as f64,
        bic: n_res as f64 * (sse_total / n_res as f64).ln() + np as f64 * (n_res as f64).ln(),
        samples: n,
        dof,
    };
    let mut notes = Vec::new();
    let mut diagnostics = diagnostics;
    for (name, f) in fit.outputs.iter().zip(&fit.fit_percent) {
        if *f < 80.0 {
            let what = model.poor_fit_advice().map(|a| format!(": {a}")).unwrap_or_default();
            diagnostics.advice.push(format!("poor fit of {name} ({f:.1} %){what}"));
        }
    }
    if info_inv.is_none() || bread_inv.is_none() {
        notes.push(
            "information matrix JᵀWJ is singular: some parameters are not identifiable from these data"
                .into(),
        );
    }
    let derived = derived(model, &parameters, &names);
    Ok(FitResult {
        model: model.name().to_string(),
        experiments: names,
        parameters,
        initial_states,
        derived,
        diagnostics,
        fit,
        correlation,
        solver,
        timing: Timing::default(),
        notes,
    })
}

/// The model's derived quantities per experiment's θ, once when every experiment gives the
/// same (no per-experiment parameter they depend on).
fn derived<M: GreyBoxModel>(
    model: &M,
    parameters: &[ParameterEstimate],
    names: &[String],
) -> Vec<DerivedEstimate> {
    let n_theta = model.parameters().len();
    let per_experiment: Vec<Vec<DerivedEstimate>> = names
        .iter()
        .map(|e| {
            let mut theta = vec![f64::NAN; n_theta];
            let mut se = vec![f64::NAN; n_theta];
            for (j, prm) in model.parameters().iter().enumerate() {
                let pick = parameters
                    .iter()
                    .find(|q| q.name == prm.name && q.experiment.as_deref() == Some(e.as_str()))
                    .or_else(|| parameters.iter().find(|q| q.name == prm.name && q.experiment.is_none()));
                if let Some(q) = pick {
                    (theta[j], se[j]) = (q.value, q.std_error);
                }
            }
            model.derived(&theta, &se)
        })
        .collect();
    match per_experiment.split_first() {
        Some((first, rest)) if rest.iter().all(|d| d == first) => first.clone(),
        _ => per_experiment
            .into_iter()
            .zip(names)
            .flat_map(|(d, e)| d.into_iter().map(|q| DerivedEstimate { experiment: Some(e.clone()), ..q }))
            .collect(),
    }
}

/// Inverse of a symmetric positive semi-definite matrix on the rows/columns with a
/// non-zero diagonal (Cholesky); the others get ∞ on the diagonal and 0 elsewhere. `None`
/// when the supported block is not positive definite.
fn inverse_on_support(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = a.nrows();
    let live: Vec<usize> = (0..n).filter(|&i| a[(i, i)] > 0.0).collect();
    let sub = DMatrix::from_fn(live.len(), live.len(), |i, j| a[(live[i], live[j])]);
    let inv = sub.cholesky()?.inverse();
    let mut out = DMatrix::zeros(n, n);
    for i in 0..n {
        if a[(i, i)] <= 0.0 {
            out[(i, i)] = f64::INFINITY;
        }
    }
    for (i, &r) in live.iter().enumerate() {
        for (j, &c) in live.iter().enumerate() {
            out[(r, c)] = inv[(i, j)];
        }
    }
    Some(out)
}
