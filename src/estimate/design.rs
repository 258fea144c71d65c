//! Experiment design: the Fisher information of any [`GreyBoxModel`] on a planned,
//! noise-free experiment, and the standard errors, intervals, correlations and optimality
//! criteria it predicts for an output-error fit — without fitting.
//!
//! One pass of the prediction-error problem at the nominal θ (the same pass a fit makes:
//! simulation with forward sensitivities, `JᵀWJ`) with output weights `Λ_i = 1/σ_i²` gives
//! the information `M = JᵀΛJ` in the scaled variables p; its inverse, mapped to θ by the
//! chain factors `dθ/dp`, is the Cramér–Rao bound on the covariance of an unbiased
//! estimate (Ljung, *System Identification*, 2nd ed., 9.3 and 13; Wang & Dowling,
//! Pyomo.DoE, AIChE J. 68 (2022) e17813). Free initial states are nuisance parameters:
//! their uncertainty is in the bound (the model parameters' block of `M⁻¹`).
//!
//! Coloured noise: an AR(1) output noise with pole a inflates every standard error by
//! `√((1 + a)/(1 − a))`, the long-run variance factor of the noise. This is exact when the
//! sensitivities vary slowly against the noise's correlation time `h/(1 − a)` (the
//! sandwich `M⁻¹ JᵀΛΣJ M⁻¹` with `JᵀΣJ ≈ σ² (1+a)/(1−a) JᵀJ`), and an approximation
//! otherwise; it is what the batch-means covariance of the fit estimates.
//!
//! [`search_shortest`] searches a list of candidate experiments for the shortest one whose
//! predicted intervals reach [`Target`]s (the caller builds and predicts the candidates).

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::problem::{FreeKind, PemProblem, ProblemOptions};
use crate::estimate::scaling::ScalingKind;
use crate::model::{GreyBoxModel, Prepared};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// Noise and options of a design prediction. Plain data; serialisable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DesignOptions {
    /// Output noise standard deviation σ_i per output \[output unit\], length n_y.
    pub noise_sd: Vec<f64>,
    /// AR(1) pole a of the output noise, in \[0, 1) (0: white).
    pub noise_pole: f64,
    /// Initial states are free nuisance parameters (as a fit's default).
    pub estimate_x0: bool,
    /// Parameter scaling (does not change the prediction, only the conditioning of the pass).
    pub scaling: ScalingKind,
}

impl Default for DesignOptions {
    fn default() -> Self {
        Self { noise_sd: Vec::new(), noise_pole: 0.0, estimate_x0: true, scaling: ScalingKind::Nominal }
    }
}

/// One parameter's predicted uncertainty.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PredictedParameter {
    /// Parameter name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Nominal value \[unit\].
    pub value: f64,
    /// Predicted standard error \[unit\] (Cramér–Rao bound; ∞ when not identifiable).
    pub std_error: f64,
    /// Predicted 95 % interval `[value − 1.96 se, value + 1.96 se]` \[unit\].
    pub ci95: [f64; 2],
    /// Error index `100 se/|value|` \[%\] (thesis 5.3, as the fit reports it).
    pub error_index_percent: f64,
}

/// A design prediction: every free model parameter's standard error and the information's
/// optimality criteria.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    /// Free model parameters, in model order.
    pub parameters: Vec<PredictedParameter>,
    /// Correlation matrix of the free model parameters (n × n).
    pub correlation: Vec<Vec<f64>>,
    /// Condition number of the relative information matrix `diag(θ) M_θθ diag(θ)` (the
    /// fit's diagnostics define it the same way).
    pub condition_number: f64,
    /// D-criterion: `log det` of the relative information of the model parameters
    /// (Schur complement over the nuisances); larger is better.
    pub d_criterion: f64,
    /// A-criterion: `Σ (se_j/θ_j)²`, the trace of the relative covariance; smaller is better.
    pub a_criterion: f64,
    /// E-criterion: the smallest eigenvalue of the relative information (Schur complement);
    /// larger is better.
    pub e_criterion: f64,
    /// Samples N (all experiments).
    pub samples: usize,
}

impl Prediction {
    /// The prediction for the parameter `name`.
    pub fn parameter(&self, name: &str) -> Option<&PredictedParameter> {
        self.parameters.iter().find(|p| p.name == name)
    }
}

/// Predicts the uncertainty of an output-error fit of `model` (parameters θ, length n_θ) to
/// `experiments` (noise-free, planned) with output noise `options`.
///
/// # Errors
/// [`Error::InvalidOption`] for a `noise_sd` of the wrong length or a non-positive σ, a pole
/// outside \[0, 1); those of [`PemProblem::new`] and of its normal-equation pass.
pub fn predict<M: GreyBoxModel>(
    model: &M,
    experiments: &[Experiment],
    theta: &[f64],
    options: &DesignOptions,
) -> Result<Prediction> {
    let ny = model.n_outputs();
    let invalid = |option: &str, reason: String| Error::InvalidOption { option: option.into(), reason };
    if options.noise_sd.len() != ny || options.noise_sd.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(invalid("noise_sd", format!("need {ny} positive values, got {:?}", options.noise_sd)));
    }
    if !(0.0..1.0).contains(&options.noise_pole) {
        return Err(invalid("noise_pole", format!("{} is outside [0, 1)", options.noise_pole)));
    }
    let preps =
        experiments.iter().map(|e| Ok((Prepared::new(model, e)?, None))).collect::<Result<Vec<_>>>()?;
    let samples = experiments.iter().map(Experiment::len).sum();
    let problem_options = ProblemOptions {
        output_weights: Some(options.noise_sd.iter().map(|s| 1.0 / (s * s)).collect()),
        estimate_x0: options.estimate_x0,
        structured_above: Some(usize::MAX),
        ..Default::default()
    };
    let rule = options.scaling.rule();
    let problem = PemProblem::new(model, preps, theta, rule.as_ref(), &problem_options)?;
    let p = problem.start_vector(theta);
    let info = problem.normal_equations(&p)?.jtj.to_dense();
    let n = info.nrows();
    // Chain factors to θ (and the relative scaling θ/(dθ/dp)) for every free entry.
    let dtheta: Vec<f64> =
        problem.free().iter().enumerate().map(|(g, f)| f.transform.dtheta_dp(p[g])).collect();
    let values: Vec<f64> = problem.free_values(&p);
    let order: Vec<usize> =
        (0..n).filter(|&g| matches!(problem.free()[g].kind, FreeKind::Parameter(_))).collect();
    let inflation = (1.0 + options.noise_pole) / (1.0 - options.noise_pole);
    let cov_p = info.clone().try_inverse().unwrap_or_else(|| DMatrix::from_element(n, n, f64::INFINITY));
    let cov = |a: usize, b: usize| inflation * cov_p[(a, b)] * dtheta[a] * dtheta[b];
    let params = model.parameters();
    let parameters = order
        .iter()
        .map(|&g| {
            let FreeKind::Parameter(j) = problem.free()[g].kind else {
                unreachable!("model parameters only")
            };
            let value = values[g];
            let se = cov(g, g).max(0.0).sqrt();
            let se = if se.is_finite() { se } else { f64::INFINITY };
            PredictedParameter {
                name: params[j].name.clone(),
                unit: params[j].unit.clone(),
                value,
                std_error: se,
                ci95: [value - 1.96 * se, value + 1.96 * se],
                error_index_percent: 100.0 * se / value.abs(),
            }
        })
        .collect::<Vec<_>>();
    let correlation = order
        .iter()
        .map(|&a| order.iter().map(|&b| cov(a, b) / (cov(a, a) * cov(b, b)).sqrt()).collect())
        .collect();
    let rel = |g: usize| values[g] / dtheta[g];
    let m = order.len();
    let info_rel = DMatrix::from_fn(m, m, |a, b| info[(order[a], order[b])] * rel(order[a]) * rel(order[b]));
    let condition_number = condition(&info_rel);
    // The relative information of the model parameters with the nuisances marginalised:
    // the inverse of their relative covariance block.
    let cov_rel =
        DMatrix::from_fn(m, m, |a, b| cov(order[a], order[b]) / (values[order[a]] * values[order[b]]));
    let a_criterion = cov_rel.trace();
    let (d_criterion, e_criterion) = match cov_rel.clone().try_inverse() {
        Some(schur) => {
            let eig = schur.clone().symmetric_eigen().eigenvalues;
            (
                eig.iter().map(|v| v.max(f64::MIN_POSITIVE).ln()).sum(),
                eig.iter().copied().fold(f64::INFINITY, f64::min),
            )
        }
        None => (f64::NEG_INFINITY, 0.0),
    };
    Ok(Prediction {
        parameters,
        correlation,
        condition_number,
        d_criterion,
        a_criterion,
        e_criterion,
        samples,
    })
}

/// Ratio of the largest to the smallest singular value of `m` (∞ when singular).
fn condition(m: &DMatrix<f64>) -> f64 {
    if m.nrows() == 0 || !m.iter().all(|v| v.is_finite()) {
        return f64::INFINITY;
    }
    let sv = m.clone().svd(false, false).singular_values;
    let (hi, lo) = (sv.max(), sv.min());
    if lo > 0.0 { hi / lo } else { f64::INFINITY }
}

/// The criterion plans are ranked by.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// D-optimality: largest `log det` of the relative information.
    #[default]
    D,
    /// A-optimality: smallest trace of the relative covariance.
    A,
    /// E-optimality: largest smallest eigenvalue of the relative information.
    E,
}

impl Criterion {
    /// A score where smaller is better, for sorting.
    pub fn score(self, p: &Prediction) -> f64 {
        match self {
            Self::D => -p.d_criterion,
            Self::A => p.a_criterion,
            Self::E => -p.e_criterion,
        }
    }

    /// Indices of `predictions`, best first.
    pub fn rank(self, predictions: &[Prediction]) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..predictions.len()).collect();
        idx.sort_by(|&a, &b| self.score(&predictions[a]).total_cmp(&self.score(&predictions[b])));
        idx
    }
}

/// A target interval: the relative 95 % half-width `1.96 se/|θ|` a parameter must reach,
/// e.g. `r_s=0.5%` (0.005) or `r_s=0.005`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Target {
    /// Parameter name.
    pub parameter: String,
    /// Relative 95 % half-width \[-\] (0.005 = ±0.5 %).
    pub half_width: f64,
}

impl std::str::FromStr for Target {
    type Err = Error;

    /// Parses `NAME=VALUE` or `NAME=VALUE%`.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (`target`) for text without `=`, or a value that is not a
    /// positive number.
    fn from_str(s: &str) -> Result<Self> {
        let bad = |reason: String| Error::InvalidOption { option: "target".into(), reason };
        let (name, value) = s
            .split_once('=')
            .ok_or_else(|| bad(format!("`{s}`: expected NAME=HALF_WIDTH, e.g. r_s=0.5%")))?;
        let (value, scale) = match value.trim().strip_suffix('%') {
            Some(v) => (v, 0.01),
            None => (value.trim(), 1.0),
        };
        let v: f64 = value.trim().parse().map_err(|_| bad(format!("`{s}`: `{value}` is not a number")))?;
        if !(v.is_finite() && v > 0.0) || name.trim().is_empty() {
            return Err(bad(format!("`{s}`: need a parameter name and a positive half-width")));
        }
        Ok(Self { parameter: name.trim().into(), half_width: v * scale })
    }
}

impl Target {
    /// The predicted relative 95 % half-width of the target's parameter (∞ when it is not
    /// identifiable).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (`target`) when the prediction has no such parameter.
    pub fn achieved(&self, p: &Prediction) -> Result<f64> {
        let q = p.parameter(&self.parameter).ok_or_else(|| Error::InvalidOption {
            option: "target".into(),
            reason: format!(
                "`{}` is not a parameter of the model ({})",
                self.parameter,
                p.parameters.iter().map(|q| q.name.as_str()).collect::<Vec<_>>().join(", ")
            ),
        })?;
        Ok(1.96 * q.std_error / q.value.abs())
    }
}

/// One candidate of a [`search_shortest`]: its prediction or why it was rejected, and
/// whether it reached every target.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Index of the candidate in the caller's list.
    pub index: usize,
    /// Its record length \[s\].
    pub length: f64,
    /// The achieved relative half-width per target (empty when rejected).
    pub achieved: Vec<f64>,
    /// Why the candidate was not predicted (e.g. a limit it reaches), if it was not.
    pub rejected: Option<String>,
    /// Whether it reaches every target.
    pub reaches: bool,
}

/// The result of [`search_shortest`]: every candidate evaluated (shortest first) and the
/// winner.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchOutcome {
    /// Candidates evaluated, by increasing length (those longer than the winner's length
    /// are not evaluated).
    pub evaluated: Vec<Candidate>,
    /// Index (into the caller's list) of the shortest candidate reaching every target; among
    /// equally long ones the one with the smallest worst ratio `achieved/target`.
    pub best: Option<usize>,
}

/// Searches `lengths.len()` candidates (record lengths `lengths[i]` \[s\]) for the shortest
/// that reaches every target: candidates are evaluated by increasing length, group by
/// group of equal length, until a group has one that does. `evaluate(i)` predicts candidate
/// i, or returns `Ok(Err(reason))` to reject it (a plan outside the experiment's limits).
///
/// # Errors
/// An error of `evaluate`, or of [`Target::achieved`] (a target naming no parameter).
pub fn search_shortest(
    lengths: &[f64],
    targets: &[Target],
    mut evaluate: impl FnMut(usize) -> Result<std::result::Result<Prediction, String>>,
) -> Result<SearchOutcome> {
    let mut order: Vec<usize> = (0..lengths.len()).collect();
    order.sort_by(|&a, &b| lengths[a].total_cmp(&lengths[b]));
    let mut evaluated: Vec<Candidate> = Vec::new();
    let mut best: Option<(usize, f64)> = None;
    for (pos, &i) in order.iter().enumerate() {
        if best.is_some() && pos > 0 && lengths[i] > lengths[order[pos - 1]] {
            break;
        }
        let candidate = match evaluate(i)? {
            Err(reason) => Candidate {
                index: i,
                length: lengths[i],
                achieved: Vec::new(),
                rejected: Some(reason),
                reaches: false,
            },
            Ok(p) => {
                let achieved = targets.iter().map(|t| t.achieved(&p)).collect::<Result<Vec<f64>>>()?;
                let worst = achieved.iter().zip(targets).map(|(a, t)| a / t.half_width).fold(0.0, f64::max);
                let reaches = worst <= 1.0;
                if reaches && best.is_none_or(|(_, w)| worst < w) {
                    best = Some((i, worst));
                }
                Candidate { index: i, length: lengths[i], achieved, rejected: None, reaches }
            }
        };
        evaluated.push(candidate);
    }
    Ok(SearchOutcome { evaluated, best: best.map(|(i, _)| i) })
}
