//! The result of a fit: estimates with uncertainty, fit statistics, solver report.
//!
//! Statistics (MODEL.md §5; Ljung, *System Identification*, 2nd ed., sections 9.3 and
//! 16.4; thesis 5.3 and appendix B):
//! - covariance `Cov(θ̂) = A⁻¹ (Σ_i σ̂_i² B_i) A⁻¹` with `A = JᵀWJ`, `B_i = Σ_k w_ki² J_kiᵀJ_ki`
//!   and `σ̂_i² = E_i²/(N − n_free/n_y)` the residual variance of output i; with uniform weights
//!   and equal noise this is the textbook `σ̂² (JᵀJ)⁻¹`;
//! - 95 % confidence interval `θ̂ ± t_{0.975, N n_y − n_free} σ_θ`;
//! - parametric error index `P_i = 100 √(E² [A⁻¹]_ii)/|θ̂_i|` with `E² = Σ w ε²`: the change
//!   of θ_i (others re-optimised) that doubles E², in percent;
//! - fit per output `100 (1 − ‖y − ŷ‖/‖y − ȳ‖)` (NRMSE fit, as MATLAB's `compare`);
//! - `AIC = N ln(E²/N) + 2 n_free`, `BIC = N ln(E²/N) + n_free ln N` over all `N = N_k n_y`
//!   residuals (Gaussian likelihood, constants dropped).

use crate::estimate::diagnostics::Diagnostics;
use serde::{Deserialize, Serialize};

/// One estimated (or fixed) parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParameterEstimate {
    /// Symbol, e.g. `r_s`.
    pub name: String,
    /// Unit, e.g. `ohm`.
    pub unit: String,
    /// Estimate θ̂ \[unit\].
    pub value: f64,
    /// Standard error \[unit\] (0 for fixed, ∞ when not identifiable): from the
    /// covariance [`FitResult::uncertainty`] names (white-noise sandwich, or batch means
    /// when the residuals are not white).
    pub std_error: f64,
    /// Standard error \[unit\] from the white-noise sandwich `A⁻¹ (Σ_i σ̂_i² B_i) A⁻¹`, whatever
    /// the residuals: equal to `std_error` for white residuals; NaN in reports written
    /// before the field existed.
    #[serde(default = "not_given")]
    pub std_error_white: f64,
    /// 95 % confidence interval `[lo, hi]` \[unit\].
    pub ci95: [f64; 2],
    /// Parametric error index \[%\] (thesis 5.3).
    pub error_index_percent: f64,
    /// Held fixed during the fit.
    pub fixed: bool,
    /// A nuisance parameter of the model (not a property of the system itself).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub nuisance: bool,
    /// The estimate sits at a bound (within [`crate::estimate::assemble::AT_BOUND`]
    /// relative): the fit is constrained there, so `std_error` and `ci95` are NaN (`null` in
    /// JSON) rather than an interval that pretends to be interior.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub at_bound: bool,
    /// Experiment this value belongs to, for per-experiment parameters; `None` when shared.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub experiment: Option<String>,
    /// Start value \[unit\].
    pub start: f64,
}

/// NaN: a figure the report does not give.
fn not_given() -> f64 {
    f64::NAN
}

/// The covariance behind the reported standard errors and intervals (Ljung, *System
/// Identification*, 2nd ed., 9.3 for the white sandwich; the batch means of
/// `problem::batches` for coloured residuals).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CovarianceMethod {
    /// The sandwich with each output's residual variance: white residuals.
    #[default]
    White,
    /// The sandwich with the score's batch-means long-run covariance (residuals not white;
    /// `crate::estimate::BatchMeans`).
    BatchMeans,
}

/// How the reported standard errors and intervals were formed, and why: the Ljung–Box test
/// (Ljung & Box, *Biometrika* 65 (1978) 297–303) at 1 % chooses the covariance.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Uncertainty {
    /// The covariance of `std_error` (and of `ci95`, but where [`Uncertainty::restricted`]).
    pub method: CovarianceMethod,
    /// Degrees of freedom of the standard errors: the residuals' (white) or the batches'
    /// less one (batch means); the t quantile of `ci95` but where
    /// [`effective_dof`](Self::effective_dof) gives a parameter fewer.
    pub dof: usize,
    /// Number of batches (batch means; 0 otherwise).
    pub batches: usize,
    /// Samples per batch (batch means; 0 otherwise).
    pub batch_samples: usize,
    /// Ljung–Box statistic of each output's residuals over the whiteness lags
    /// ([`crate::estimate::metrics::Whiteness::ljung_box`]), length n_y.
    pub ljung_box: Vec<f64>,
    /// Its 1 % critical value: above it the residuals are not white.
    pub ljung_box_critical: f64,
    /// Whether the batches entered by the delete-one-batch jackknife (instrumental
    /// variables, `crate::estimate::iv`) rather than the batch means' sandwich; `false` in
    /// reports written before the field existed (and not written when `false`).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub jackknife: bool,
    /// Whether `ci95` is the batches' restricted interval (instrumental variables,
    /// `crate::estimate::restricted`) rather than `± t·std_error`; `false` in older reports.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub restricted: bool,
    /// Per free parameter (in the estimator's order), the effective degrees of freedom of
    /// the delete-one-batch jackknife's variance (`crate::estimate::jackknife`, Bell &
    /// McCaffrey 2002), in `[1, dof]`: fewer than `dof` where a few batches carry the
    /// parameter; its `± t·std_error` interval takes t at them
    /// ([`Uncertainty::t_quantile_of`]). Empty
    /// without the jackknife, and in older reports (then `dof` for every parameter).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effective_dof: Vec<f64>,
}

impl Uncertainty {
    /// The choice for residuals of `n` samples per output whose whiteness per output is
    /// `whiteness`: the batch means `batch_means` when any output fails the Ljung–Box test
    /// and they are given, with `B − 1` degrees of freedom; otherwise white, with `dof`.
    pub fn choose(
        whiteness: &[crate::estimate::metrics::Whiteness],
        n: usize,
        dof: usize,
        batch_means: Option<&crate::estimate::BatchMeans>,
    ) -> Self {
        let batch_means = batch_means.filter(|_| !whiteness.iter().all(|w| w.is_white(n)));
        Self {
            method: if batch_means.is_some() {
                CovarianceMethod::BatchMeans
            } else {
                CovarianceMethod::White
            },
            dof: batch_means.map_or(dof, |b| b.batches - 1),
            batches: batch_means.map_or(0, |b| b.batches),
            batch_samples: batch_means.map_or(0, |b| b.batch_samples),
            ljung_box: whiteness.iter().map(|w| w.ljung_box(n)).collect(),
            ljung_box_critical: whiteness
                .first()
                .map_or(0.0, crate::estimate::metrics::Whiteness::ljung_box_critical),
            jackknife: false,
            restricted: false,
            effective_dof: Vec::new(),
        }
    }

    /// The 0.975 quantile of Student's t of free parameter `j`'s `± t·std_error` interval:
    /// at its [`effective_dof`](Self::effective_dof) where given (in `[1, dof]`, 1 where not
    /// finite; between whole numbers `ln t` interpolated linearly in 1/ν, within 3 % of the
    /// exact quantile), else at [`dof`](Self::dof); ∞ when `dof` is 0.
    pub fn t_quantile_of(&self, j: usize) -> f64 {
        let t = crate::estimate::t_quantile_975;
        let Some(&nu) = self.effective_dof.get(j).filter(|_| self.dof > 0) else {
            return t(self.dof);
        };
        let nu = if nu.is_finite() { nu.clamp(1.0, self.dof as f64) } else { 1.0 };
        let (lo, hi) = (nu.floor(), nu.ceil());
        if lo == hi {
            return t(lo as usize);
        }
        let w = (1.0 / lo - 1.0 / nu) / (1.0 / lo - 1.0 / hi);
        (t(lo as usize).ln() + w * (t(hi as usize).ln() - t(lo as usize).ln())).exp()
    }

    /// Whether the residuals are white: every output's Ljung–Box statistic at or below its
    /// 1 % critical value (Ljung & Box 1978, as [`choose`](Self::choose) tests them);
    /// `false` without the statistics (an empty `ljung_box` or no critical value).
    pub fn white(&self) -> bool {
        !self.ljung_box.is_empty()
            && self.ljung_box_critical > 0.0
            && self.ljung_box.iter().all(|&q| q <= self.ljung_box_critical)
    }

    /// The batch means this uncertainty took from those offered to [`choose`](Self::choose).
    pub fn taken<'b>(
        &self,
        batch_means: Option<&'b crate::estimate::BatchMeans>,
    ) -> Option<&'b crate::estimate::BatchMeans> {
        batch_means.filter(|_| self.method == CovarianceMethod::BatchMeans)
    }
}

pub(crate) use crate::model::DerivedEstimate;

/// Goodness of fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitStatistics {
    /// Output names, length n_y.
    pub outputs: Vec<String>,
    /// Output units (e.g. `A`), length n_y; empty in reports written before the field
    /// existed.
    #[serde(default)]
    pub output_units: Vec<String>,
    /// NRMSE fit per output \[%\], length n_y.
    pub fit_percent: Vec<f64>,
    /// RMS residual per output \[output unit\], length n_y.
    pub rms_residual: Vec<f64>,
    /// Criterion value at the estimate, `V = Σ β_k Σ_i Λ_i ρ(ε_ki)` with ρ the loss
    /// (`½ε²` for the quadratic loss; Huber's ρ with `--huber`).
    pub loss: f64,
    /// Mean squared residual over all outputs, `E²/(N n_y)`.
    pub mse: f64,
    /// Akaike information criterion `N ln(E²/N) + 2 n_free` over all `N = N_k n_y` residuals,
    /// E² the unweighted residual sum of squares (Gaussian likelihood with one variance,
    /// constants dropped; Ljung 16.4).
    pub aic: f64,
    /// Bayesian information criterion `N ln(E²/N) + n_free ln N` (as `aic`; Schwarz 1978).
    pub bic: f64,
    /// Akaike's final prediction error `(E²/N)(1 + n_free/N)/(1 − n_free/N)` over all `N = N_k n_y`
    /// residuals (Ljung 16.4).
    #[serde(default)]
    pub fpe: f64,
    /// Residual whiteness per output (normalised autocorrelation at lags 1–25 and its 95 %
    /// bound; Ljung 16.6), length n_y.
    #[serde(default)]
    pub whiteness: Vec<crate::estimate::metrics::Whiteness>,
    /// Residual samples per output N (first samples excluded).
    pub samples: usize,
    /// Degrees of freedom `N n_y − n_free`.
    pub dof: usize,
    /// Samples per output the criterion counts (non-zero weight), when some were weighted
    /// out (e.g. a dead-time mask); `fit_percent`, `rms_residual`, `mse`, FPE, AIC and BIC
    /// are then over these samples alone. `None`: every sample counts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub counted: Option<usize>,
    /// The k-step-ahead prediction horizon whose residuals these are; `None`: simulation
    /// (output error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub horizon: Option<usize>,
}

pub(crate) use crate::estimate::solver::SolverReport;

/// Wall-clock timing \[s\]. Fields may be added (as `solve_s` was): outside the crate build
/// one with `..Default::default()`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Timing {
    /// Reading the logs.
    pub read_s: f64,
    /// The fit (start estimate, hold selection, optimisation, statistics).
    pub fit_s: f64,
    /// Everything.
    pub total_s: f64,
    /// Of `fit_s`, the solver's iterations of the reported estimate \[s\], from its start to
    /// its end (its evaluations and normal equations, the pass at the start included where an
    /// automatic hold choice made it; with a Huber loss both runs; not the start estimate, the
    /// setup and residual checks or the statistics): a prediction-error fit's optimisation
    /// alone, what another optimiser from the same start would do. `None` for the estimates without a
    /// solver of their own (linear least squares, steady state, instrumental variables) and
    /// in reports written before the field existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve_s: Option<f64>,
}

/// Everything a fit produces; serialises to the JSON report.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitResult {
    /// Model name, e.g. `pmsm_spm`.
    pub model: String,
    /// Names of the experiments fitted.
    pub experiments: Vec<String>,
    /// Estimates, model parameter order (per-experiment copies follow each other).
    pub parameters: Vec<ParameterEstimate>,
    /// Estimated initial states (`x0_<state>`), one set per experiment;
    /// empty when the first measurement is taken as the initial state.
    pub initial_states: Vec<ParameterEstimate>,
    /// Quantities the model derives from its parameters ([`crate::model::GreyBoxModel::derived`]).
    pub derived: Vec<DerivedEstimate>,
    /// Identifiability diagnostics and advice.
    pub diagnostics: Diagnostics,
    /// Goodness of fit.
    pub fit: FitStatistics,
    /// Correlation matrix of the free model parameters (order of the free entries of
    /// `parameters`; initial states excluded). A fit kept by arrowhead blocks (more than
    /// [`STRUCTURED_ABOVE`](crate::estimate::problem::STRUCTURED_ABOVE) free parameters)
    /// gives that of the shared parameters only, as its identifiability diagnostics: the
    /// per-experiment ones would make it grow with the square of the experiments.
    pub correlation: Vec<Vec<f64>>,
    /// Labels of the rows and columns of `correlation` (`name` or `name[experiment]`);
    /// empty in reports written before the field existed.
    #[serde(default)]
    pub correlation_names: Vec<String>,
    /// How the standard errors and intervals were formed (white-noise or batch-means
    /// covariance) and the whiteness test that chose.
    #[serde(default)]
    pub uncertainty: Uncertainty,
    /// Solver report.
    pub solver: SolverReport,
    /// The free model parameters after each solver iteration, the start first [their
    /// units]: rows 1 + iterations (a robust fit: the quadratic run's, then the Huber
    /// run's), each row the free entries of `parameters` in order; empty
    /// when there was no iteration (closed form, all parameters fixed).
    #[serde(default)]
    pub parameter_trace: Vec<Vec<f64>>,
    /// Timing.
    pub timing: Timing,
    /// Remarks on the fit (start estimate, hold selection).
    pub notes: Vec<String>,
    /// What a reader must not miss: results that are not trustworthy (not converged,
    /// non-finite statistics, a parameter at a bound, a likely setup mistake) and the
    /// conventions assumed where the data cannot tell.
    #[serde(default)]
    pub warnings: Vec<Warning>,
}

/// A warning of a fit report, with a stable code for scripts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Warning {
    /// Stable code, e.g. `not_converged`, `parameter_at_bound`; models add their own.
    pub code: String,
    /// What was found and what to do about it.
    pub message: String,
    /// While this holds the estimates are not to be trusted (`greybox fit` then exits
    /// with code 3); `false` for information a reader must know (an assumed convention).
    pub untrusted: bool,
}

impl Warning {
    /// A warning that makes the result untrusted.
    pub fn untrusted(code: &str, message: String) -> Self {
        Self { code: code.into(), message, untrusted: true }
    }
    /// A warning that informs only.
    pub fn notice(code: &str, message: String) -> Self {
        Self { code: code.into(), message, untrusted: false }
    }
}

impl FitResult {
    /// Whether the fit converged and no warning makes it untrusted.
    pub fn trusted(&self) -> bool {
        self.solver.success && self.warnings.iter().all(|w| !w.untrusted)
    }
    /// Why the fit is not trusted: the codes of its untrusted warnings, with
    /// `not_converged` first when the solver did not converge and no warning says so;
    /// empty exactly when [`FitResult::trusted`].
    pub fn untrusted_codes(&self) -> Vec<String> {
        let mut codes: Vec<String> =
            self.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.clone()).collect();
        if !self.solver.success && !codes.iter().any(|c| c == "not_converged") {
            codes.insert(0, "not_converged".into());
        }
        codes
    }
    /// The estimate of the parameter called `name` (first match), if any.
    pub fn parameter(&self, name: &str) -> Option<&ParameterEstimate> {
        self.parameters.iter().find(|p| p.name == name)
    }
    /// The derived quantity called `name` (first match), if any.
    pub fn derived(&self, name: &str) -> Option<&DerivedEstimate> {
        self.derived.iter().find(|p| p.name == name)
    }
    /// The JSON report (pretty-printed). Non-finite numbers (an infinite standard error of
    /// an unidentifiable parameter, its interval) are written as `null`, as JSON has no ∞.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = if self.untrusted { "WARNING" } else { "notice" };
        write!(f, "{kind} [{}]: {}", self.code, self.message)
    }
}

/// The report table ([`FitResult::document`] without model conventions, as plain text).
impl std::fmt::Display for FitResult {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.document(&[]).to_text())
    }
}
