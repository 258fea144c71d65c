//! Linear least squares (LS) and weighted least squares (WLS) on the dq voltage equations
//! (thesis section 5.2.1, MODEL.md §5).
//!
//! Both voltage equations are stacked, one row each per sample interval k, with the
//! forward difference `(i[k+1] − i[k])/h` and interval means of current and speed, so that
//! `u[k]` (the period-mean voltage) is paired with the step it drives (MODEL.md §4):
//!
//! ```text
//! SPM, θ = (R_s, L_s, K_e):
//!   u_q: [ i_q,  di_q/dt + n_p ω_m i_d,  √(2/3) ω_m ]
//!   u_d: [ i_d,  di_d/dt − n_p ω_m i_q,  0 ]
//! IPM, θ = (R_s, L_d, L_q, K_e):
//!   u_d: [ i_d,  di_d/dt,  −n_p ω_m i_q,  0 ]
//!   u_q: [ i_q,  n_p ω_m i_d,  di_q/dt,  √(2/3) ω_m ]
//! ```
//!
//! [`weighted_least_squares`] optionally passes every signal through the same zero-phase
//! Butterworth low-pass first ([`crate::estimate::filter`]) and weights both rows of
//! interval k by the sample weight β_{k+1} of the sample that interval ends in (thesis
//! eq. 5.11). The rows are streamed into a tall-skinny QR of the row-weighted regressors
//! ([`StreamedLeastSquares`]; no rows × n_θ matrix is formed); `R` of that decomposition also gives the
//! rank check and `(ΦᵀWΦ)⁻¹` for the standard errors and the parametric error index
//! (thesis 5.3). With noisy currents the derivative column is errors-in-variables and `L`
//! comes out low: use the result as the start of the prediction-error fit, not as the
//! answer.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::Uncertainty;
use crate::estimate::filter::{self, Butterworth};
use crate::estimate::linear::{LinearSolution, StreamedLeastSquares};
use crate::estimate::metrics::Whiteness;
use crate::estimate::problem::{BlockScores, ScoreSeries, TARGET_BATCHES};
use crate::estimate::weighting::{Uniform, Weighting};
use crate::pmsm::log::signals::{DqView, channel};
use crate::pmsm::model::kind::MotorKind;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::fmt;

use super::regression::Regression;

/// Options of [`weighted_least_squares`]. Plain data with defaults; serialisable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LinearOptions {
    /// Cutoff f_c \[Hz\] of the zero-phase Butterworth low-pass applied to every signal
    /// (u_d, u_q, i_d, i_q, w_m) before the regressors are formed; `None` = no filter.
    /// Must lie in `(0, 1/(2h))` for every experiment.
    pub prefilter: Option<f64>,
    /// Order of that filter: even, 2..=[`filter::MAX_ORDER`]; default 4.
    pub filter_order: usize,
}

impl Default for LinearOptions {
    fn default() -> Self {
        Self { prefilter: None, filter_order: filter::DEFAULT_ORDER }
    }
}

/// Result of the linear least-squares estimate.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LinearEstimate {
    /// The regression model.
    pub kind: MotorKind,
    /// Parameter names, e.g. `["r_s", "l_s", "k_e"]`, length n_θ.
    pub names: Vec<String>,
    /// Parameter units, e.g. `["ohm", "H", "V s/rad"]` (as in the fit report), length n_θ.
    pub units: Vec<String>,
    /// Estimates θ̂ in SI units (Ω, H, V s/rad), length n_θ.
    pub theta: Vec<f64>,
    /// Standard errors of θ̂ (same units as θ̂, length n_θ; NaN without degrees of
    /// freedom): `σ̂² (ΦᵀWΦ)⁻¹` when the equation errors pass the whiteness test, else
    /// from the batch means of the score ([`uncertainty`](Self::uncertainty) says which).
    /// Neither removes the errors-in-variables bias of noisy currents: the regression is a
    /// start, not the answer.
    pub std_error: Vec<f64>,
    /// The white-noise standard errors `σ̂² (ΦᵀWΦ)⁻¹`, whatever the equation errors.
    #[serde(default)]
    pub std_error_white: Vec<f64>,
    /// How `std_error` was formed.
    #[serde(default)]
    pub uncertainty: Uncertainty,
    /// Parametric error index `P_i = 100 √(E² [(ΦᵀWΦ)⁻¹]_ii) / |θ̂_i|` \[%\] (thesis 5.3,
    /// appendix B): the relative change of θ_i (the others re-optimised) that doubles E².
    /// Small is well excited. Length n_θ.
    pub error_index_percent: Vec<f64>,
    /// Weighted squared equation error `E² = Σ β r²` at θ̂ \[V²\].
    pub e2: f64,
    /// Unweighted RMS equation residual of the d and q rows \[V\], `[d, q]`.
    pub rms_residual: [f64; 2],
    /// Number of regression rows (2 per sample interval, all experiments).
    pub rows: usize,
    /// The sample weighting, by [`Weighting::name`].
    pub weighting: String,
    /// The options used.
    pub options: LinearOptions,
    /// Degrees of freedom of the standard errors (rows of positive weight − n_θ).
    pub dof: usize,
    /// Whiteness of the d and q equation errors (Ljung 16.6).
    pub whiteness: Vec<crate::estimate::metrics::Whiteness>,
    /// `(ΦᵀWΦ)⁻¹` (n_θ × n_θ): the correlation of the estimates.
    pub inverse: Vec<Vec<f64>>,
    /// NRMSE fit of the d and q voltage equations \[%\]: `100 (1 − ‖u − Φθ̂‖/‖u − ū‖)`.
    pub fit_percent: [f64; 2],
}

impl LinearEstimate {
    /// Estimate of parameter `name` \[SI\], if the model has it.
    pub fn value(&self, name: &str) -> Option<f64> {
        self.names.iter().position(|n| n == name).map(|i| self.theta[i])
    }
}

impl fmt::Display for LinearEstimate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let filter = match self.options.prefilter {
            Some(fc) => format!("prefilter Butterworth order {} at {fc} Hz", self.options.filter_order),
            None => "no prefilter".into(),
        };
        writeln!(
            f,
            "linear least squares ({:?}; weighting {}; {filter}): {} rows, E² = {:.6e} V²",
            self.kind, self.weighting, self.rows, self.e2
        )?;
        writeln!(
            f,
            "  {:<10} {:>14} {:>12} {:>14}  unit",
            "parameter", "value", "std error", "error index %"
        )?;
        for i in 0..self.theta.len() {
            writeln!(
                f,
                "  {:<10} {:>14.7e} {:>12.3e} {:>14.4}  {}",
                self.names[i], self.theta[i], self.std_error[i], self.error_index_percent[i], self.units[i]
            )?;
        }
        writeln!(f, "  rms residual: d {:.4e} V, q {:.4e} V", self.rms_residual[0], self.rms_residual[1])
    }
}

/// Unweighted, unfiltered least-squares estimate of θ from one or more experiments of one
/// motor: [`weighted_least_squares`] with [`Uniform`] weights and default options.
///
/// # Errors
/// Those of [`weighted_least_squares`].
///
/// # Example
/// ```no_run
/// use greybox::pmsm::{least_squares, MotorKind};
/// # fn main() -> greybox::Result<()> {
/// let e = greybox::pmsm::read_log("data/sample.csv.gz", &Default::default())?;
/// let ls = least_squares(&[e], 4, MotorKind::Spm)?;
/// println!("{ls}");
/// # Ok(()) }
/// ```
pub fn least_squares(experiments: &[Experiment], n_p: u32, kind: MotorKind) -> Result<LinearEstimate> {
    weighted_least_squares(experiments, n_p, kind, &Uniform, &LinearOptions::default())
}

/// Weighted least-squares estimate of θ (model order of `kind`) from one or more
/// experiments of one motor, `min Σ_k β_{k+1} (|r_d,k|² + |r_q,k|²)` over the stacked
/// voltage-equation residuals r of every interval k.
///
/// Every signal (u_d, u_q, i_d, i_q, w_m) of each experiment is first filtered with the
/// same zero-phase Butterworth low-pass when `options.prefilter` is set; the weights β come
/// from `weighting` on the experiment as given (unfiltered).
///
/// # Errors
/// [`Error::InvalidOption`] for an empty experiment list (option `experiments`),
/// experiments with different pole-pair numbers (`pole pairs`), a filter order that is 0,
/// odd or too large (`filter_order`), a cutoff not in `(0, 1/(2h))` for some experiment
/// (`prefilter`, naming the experiment), weights that are negative, non-finite, all zero or
/// of the wrong length (`weighting`); [`Error::Numerical`] when a parameter is not
/// excited (its regressor column is zero) or not identifiable (its column is numerically a
/// combination of the earlier ones, [`crate::estimate::linear::RANK_TOLERANCE`]), naming the parameter, or when the
/// solution is not finite.
///
/// # Source
/// Thesis 5.2.1 (regression), eq. 5.11 (sample weights), 5.3 and appendix B (error index);
/// MODEL.md §4–5.
pub fn weighted_least_squares(
    experiments: &[Experiment],
    n_p: u32,
    kind: MotorKind,
    weighting: &dyn Weighting,
    options: &LinearOptions,
) -> Result<LinearEstimate> {
    experiments.first().ok_or_else(|| Error::InvalidOption {
        option: "experiments".into(),
        reason: "no experiment given".into(),
    })?;

    crate::pmsm::log::signals::check_pole_pairs(n_p)?;
    filter::check_order(options.filter_order).map_err(|e| rename_option(e, "filter_order", None))?;
    let names: Vec<String> = kind.parameter_names().iter().map(|s| s.to_string()).collect();
    let cols = names.len();
    // The filtered copies (kept for the residual pass), then each log's view validated
    // once (of its filtered copy where there is one) for both passes, and √β per sample.
    let filtered = experiments
        .iter()
        .map(|e| match options.prefilter {
            Some(fc) => {
                let bw = Butterworth::try_new(options.filter_order, fc, e.h())
                    .map_err(|err| rename_option(err, "prefilter", Some(e.name())))?;
                Ok(Some(bw.filtfilt_experiment(e, &[channel::THETA_M])?))
            }
            None => Ok(None),
        })
        .collect::<Result<Vec<_>>>()?;
    let views = experiments
        .iter()
        .zip(&filtered)
        .map(|(e, copy)| DqView::try_new(copy.as_ref().unwrap_or(e)))
        .collect::<Result<Vec<_>>>()?;
    let mut weights = Vec::with_capacity(experiments.len());
    let mut ls = StreamedLeastSquares::new(cols);
    let mut sum = [0.0; 2];
    for (e, view) in experiments.iter().zip(&views) {
        let (u_d, u_q) = view.terminal_voltage()?;
        let reg = Regression::new(view, u_d, u_q, n_p, kind);
        let sqrt_beta: Option<Vec<f64>> = if weighting.is_uniform() {
            None
        } else {
            let beta = weighting.weights(e)?;
            if beta.len() != e.len() {
                return Err(Error::InvalidOption {
                    option: "weighting".into(),
                    reason: format!(
                        "{} gave {} weights for the {} samples of `{}`",
                        weighting.name(),
                        beta.len(),
                        e.len(),
                        e.name()
                    ),
                });
            }
            Some(beta.iter().map(|b| b.sqrt()).collect())
        };
        reg.for_each(|k, d, q, u| {
            // Interval k ends in sample k + 1: both its rows take β_{k+1}.
            let sw = sqrt_beta.as_ref().map_or(1.0, |b| b[k + 1]);
            ls.push(&d[..cols], u[0], sw);
            ls.push(&q[..cols], u[1], sw);
            sum[0] += u[0];
            sum[1] += u[1];
        });
        weights.push(sqrt_beta);
    }
    let rows = ls.rows();
    let sol = ls.solve(&names)?;
    // Residual pass: d and q equation errors, per experiment for the whiteness lags.
    let mean = sum.map(|s| s / (rows / 2).max(1) as f64);
    let (mut sse, mut sst) = ([0.0; 2], [0.0; 2]);
    let mut res = [Vec::with_capacity(rows / 2), Vec::with_capacity(rows / 2)];
    let mut segments = Vec::with_capacity(experiments.len());
    // The score β φ r summed per block of intervals, for the batch means.
    let mut scores = ScoreSeries::new(cols);
    for (view, sqrt_beta) in views.iter().zip(&weights) {
        let (u_d, u_q) = view.terminal_voltage()?;
        let reg = Regression::new(view, u_d, u_q, n_p, kind);
        let mut blocks = BlockScores::new(cols);
        reg.for_each(|k, d, q, u| {
            let beta = sqrt_beta.as_ref().map_or(1.0, |b| b[k + 1] * b[k + 1]);
            for (c, row) in [d, q].iter().enumerate() {
                let r = u[c] - row[..cols].iter().zip(&sol.theta).map(|(a, b)| a * b).sum::<f64>();
                sse[c] += r * r;
                sst[c] += (u[c] - mean[c]).powi(2);
                res[c].push(r);
                for (s, x) in blocks.open_mut().iter_mut().zip(&row[..cols]) {
                    *s += beta * x * r;
                }
            }
            blocks.count();
        });
        blocks.close();
        scores.add_plain(&blocks);
        segments.push(reg.intervals());
    }
    // Whiteness of the d and q equation errors, lags within each experiment.
    let whiteness: Vec<Whiteness> = res
        .iter()
        .map(|r| {
            let mut parts = Vec::with_capacity(segments.len());
            let mut at = 0;
            for &len in &segments {
                parts.push(&r[at..at + len]);
                at += len;
            }
            crate::estimate::metrics::whiteness(&parts, crate::estimate::WHITENESS_LAGS)
        })
        .collect();
    let half = (rows / 2) as f64;
    let (std_error, uncertainty) = covariance(&sol, &whiteness, &scores, rows / 2);
    Ok(LinearEstimate {
        kind,
        names,
        units: kind.parameter_units().iter().map(|s| s.to_string()).collect(),
        std_error,
        std_error_white: sol.std_error.clone(),
        uncertainty,
        error_index_percent: sol.error_index_percent,
        theta: sol.theta,
        e2: sol.e2,
        whiteness,
        dof: sol.dof,
        inverse: sol.inverse,
        fit_percent: [0, 1]
            .map(|c| if sst[c] > 0.0 { 100.0 * (1.0 - (sse[c] / sst[c]).sqrt()) } else { f64::NAN }),
        rms_residual: [(sse[0] / half).sqrt(), (sse[1] / half).sqrt()],
        rows,
        weighting: weighting.name(),
        options: options.clone(),
    })
}

/// The standard errors of the regression and how they were formed: white
/// (`σ̂² (ΦᵀWΦ)⁻¹`) when the d and q equation errors of all `n` intervals pass the whiteness
/// test, else the batch means of the score `Σ β φ r` (`estimate::BatchMeans`) in the
/// sandwich `(ΦᵀWΦ)⁻¹ Ω (ΦᵀWΦ)⁻¹`.
fn covariance(
    sol: &LinearSolution,
    whiteness: &[Whiteness],
    scores: &ScoreSeries,
    n: usize,
) -> (Vec<f64>, Uncertainty) {
    let offered = scores.batch_means(TARGET_BATCHES);
    let uncertainty = Uncertainty::choose(whiteness, n, sol.dof, offered.as_ref());
    let bm = uncertainty.taken(offered.as_ref());
    let se = match bm {
        None => sol.std_error.clone(),
        Some(b) => {
            let m = sol.inverse.len();
            let inv = DMatrix::from_fn(m, m, |i, j| sol.inverse[i][j]);
            let cov = &inv * &b.meat * &inv;
            (0..m).map(|j| cov[(j, j)].max(0.0).sqrt()).collect()
        }
    };
    (se, uncertainty)
}

/// Renames the option of an [`Error::InvalidOption`] from the filter to the field of
/// [`LinearOptions`], adding the experiment's name.
fn rename_option(err: Error, option: &str, experiment: Option<&str>) -> Error {
    match err {
        Error::InvalidOption { reason, .. } => Error::InvalidOption {
            option: option.into(),
            reason: match experiment {
                Some(name) => format!("{reason} (experiment `{name}`)"),
                None => reason,
            },
        },
        other => other,
    }
}
