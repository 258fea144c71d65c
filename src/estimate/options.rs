//! The options of a prediction-error fit ([`PemOptions`]).

use super::{DiagnosticThresholds, RunOptions, ScalingKind, SolverKind, Tolerances, WeightingKind};
use serde::{Deserialize, Serialize};

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
    /// Sample weighting β_k (thesis eq. 5.11); a custom rule goes through [`fit_with_weighting`](super::fit_with_weighting).
    pub weighting: WeightingKind,
    /// Robust fit: Huber loss with threshold `δ_i = c σ̂_i` per output, where `c` is this
    /// value (1.345 is the usual choice: 95 % efficiency under Gaussian noise) and σ̂_i the
    /// robust scale `1.4826 MAD` of the residuals of a preceding quadratic fit. `None` =
    /// quadratic loss.
    pub huber: Option<f64>,
    /// Residual prefilter L(q): cutoff \[Hz\] of a causal low-pass Butterworth filter of
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
    /// Report the solver's iterations to the process's
    /// [`ProgressObserver`](super::ProgressObserver) (the command line installs a
    /// spinner on stderr, shown only when stderr is a terminal); none installed: no effect.
    pub progress: bool,
    /// Levenberg-Marquardt's initial damping λ₀ ([`RunOptions::initial_damping`]); `None`:
    /// [`DEFAULT_DAMPING`](super::DEFAULT_DAMPING) here, [`CLOSE_START_DAMPING`](super::CLOSE_START_DAMPING) in the PMSM fits that start from
    /// the linear least-squares estimate. Dimensionless (relative to `diag(JᵀWJ)`); a value
    /// not positive and finite is [`Error::InvalidOption`](crate::Error::InvalidOption) naming `initial_damping`.
    pub initial_damping: Option<f64>,
    /// Levenberg-Marquardt's geodesic acceleration ([`RunOptions::geodesic`]): off by
    /// default; worth trying on a curve fit whose run crawls along a curved valley
    /// (docs/performance.md has MINPACK's test set with and without it). No effect with the
    /// Huber loss or in the errors-in-variables correction's refit, which take plain steps.
    pub geodesic: bool,
    /// Free parameters above which the normal equations and statistics are kept by the
    /// blocks of their arrowhead structure ([`Arrowhead`](super::Arrowhead)); `None`:
    /// [`STRUCTURED_ABOVE`](super::STRUCTURED_ABOVE) (64). Not serialised: how the sums are stored, not
    /// what is fitted.
    #[serde(skip)]
    pub structured_above: Option<usize>,
}

impl PemOptions {
    /// The options of the solver run.
    pub fn run_options(&self) -> RunOptions {
        RunOptions {
            solver: self.solver,
            tolerances: self.tolerances,
            progress: self.progress,
            initial_damping: self.initial_damping,
            geodesic: self.geodesic,
        }
    }
}

impl Default for PemOptions {
    fn default() -> Self {
        Self {
            solver: SolverKind::Auto,
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
            initial_damping: None,
            geodesic: false,
            structured_above: None,
        }
    }
}
