//! Simulated against measured outputs of a model at given parameters, on any experiment:
//! the data of MATLAB's `compare` (Ljung, *System Identification*, 16.5: validation on data
//! not used in the fit).

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::{Metrics, metrics};
use crate::model::{GreyBoxModel, Prepared};
use crate::simulate::{SimOptions, simulate};
use serde::{Deserialize, Serialize};

/// Lags of the residual whiteness test in a comparison (those of a fit).
use crate::estimate::WHITENESS_LAGS;

/// One experiment simulated at θ from its measured first state, against its measurement.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    /// Experiment name.
    pub experiment: String,
    /// Sample time h \[s\].
    pub h: f64,
    /// Time of the first sample \[s\] in the log's own clock ([`Experiment::t0`]): sample k
    /// is at `t0 + k h`.
    #[serde(default)]
    pub t0: f64,
    /// Output names (channels), length n_y.
    pub outputs: Vec<String>,
    /// Output units (SI), length n_y (empty when read from a comparison saved without them).
    #[serde(default)]
    pub units: Vec<String>,
    /// Measured outputs, row-major `N × n_y`.
    pub y: Vec<f64>,
    /// Simulated outputs, row-major `N × n_y`.
    pub y_hat: Vec<f64>,
    /// Fit statistics of the comparison (over the counted samples).
    pub metrics: Metrics,
    /// Per sample, whether the fit counted it (non-zero weight), length N; empty when every
    /// sample counts. A sample not counted has a simulated value but no residual.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub counted: Vec<bool>,
    /// The k-step-ahead prediction horizon of `y_hat`; `None`: simulation (output error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub horizon: Option<usize>,
}

impl Comparison {
    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.y.len() / self.outputs.len().max(1)
    }
    /// Whether there is no sample.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Measured output `i` over time, length N (empty for `i ≥ n_y`).
    pub fn measured(&self, i: usize) -> Vec<f64> {
        let ny = self.outputs.len();
        if i >= ny {
            return Vec::new();
        }
        self.y.iter().skip(i).step_by(ny).copied().collect()
    }
    /// Simulated output `i` over time, length N (empty for `i ≥ n_y`).
    pub fn simulated(&self, i: usize) -> Vec<f64> {
        let ny = self.outputs.len();
        if i >= ny {
            return Vec::new();
        }
        self.y_hat.iter().skip(i).step_by(ny).copied().collect()
    }
    /// Whether sample k counts (has a residual): see [`Comparison::counted`].
    pub fn counts(&self, k: usize) -> bool {
        self.counted.get(k).copied().unwrap_or(true)
    }
    /// Unit of output `i` (empty when unknown).
    pub fn unit(&self, i: usize) -> &str {
        self.units.get(i).map_or("", String::as_str)
    }
    /// The comparison as CSV text: `t, <output>, <output>_sim, …` \[s, output units\].
    pub fn to_csv(&self) -> String {
        let ny = self.outputs.len();
        let mut out = String::from("t");
        for o in &self.outputs {
            out.push_str(&format!(",{o},{o}_sim"));
        }
        out.push('\n');
        for k in 0..self.y.len() / ny.max(1) {
            out.push_str(&format!("{}", self.t0 + k as f64 * self.h));
            for i in 0..ny {
                out.push_str(&format!(",{},{}", self.y[k * ny + i], self.y_hat[k * ny + i]));
            }
            out.push('\n');
        }
        out
    }
}

/// Simulates `model` at `theta` (length n_θ) on `experiment` from the measured first state
/// and compares with the measured outputs; `n_params` is the number of estimated
/// parameters (for FPE, AIC, BIC).
///
/// # Errors
/// Those of [`Prepared::new`] (a missing channel) and of [`simulate`] (θ of the wrong
/// length, an invalid θ, a diverging simulation).
pub fn compare<M: GreyBoxModel>(
    model: &M,
    experiment: &Experiment,
    theta: &[f64],
    n_params: usize,
) -> Result<Comparison> {
    compare_from(model, experiment, theta, None, n_params)
}

/// As [`compare`], simulated from the initial state `x0` (length n_x; `None`: the measured
/// first state), e.g. the one a fit estimated.
///
/// # Errors
/// As [`compare`]; [`crate::Error::InvalidOption`] for an `x0` not of length n_x.
pub fn compare_from<M: GreyBoxModel>(
    model: &M,
    experiment: &Experiment,
    theta: &[f64],
    x0: Option<&[f64]>,
    n_params: usize,
) -> Result<Comparison> {
    compare_predicted(model, experiment, theta, x0, n_params, None, Vec::new())
}

/// As [`compare_from`], with the fit's predictor and the samples it counted: `y_hat` the
/// k-step-ahead prediction (`horizon`, restarting from the measured state every k samples;
/// `None`: simulation), and `counted` (length N, or empty for all) the samples whose
/// residuals the metrics take, so that the comparison shows the residual the fit minimised
/// (Ljung 3.2: the k-step predictor).
///
/// # Errors
/// As [`compare_from`]; [`crate::Error::InvalidOption`] (option `counted`) when `counted`
/// is neither empty nor of length N, or counts fewer than two samples.
pub fn compare_predicted<M: GreyBoxModel>(
    model: &M,
    experiment: &Experiment,
    theta: &[f64],
    x0: Option<&[f64]>,
    n_params: usize,
    horizon: Option<usize>,
    counted: Vec<bool>,
) -> Result<Comparison> {
    let prep = Prepared::new(model, experiment)?;
    let y_hat = simulate(model, &prep, theta, &SimOptions { x0, horizon, ..SimOptions::default() })?;
    let (outputs, units): (Vec<String>, Vec<String>) =
        model.outputs().into_iter().map(|o| (o.name, o.unit)).unzip();
    let y = prep.y_rows();
    let ny = outputs.len().max(1);
    let n = y.len() / ny;
    let metrics = if counted.is_empty() {
        metrics(&outputs, &y, &y_hat, n_params, WHITENESS_LAGS)?
    } else {
        let kept = counted.iter().filter(|c| **c).count();
        if counted.len() != n || kept < 2 {
            return Err(crate::Error::InvalidOption {
                option: "counted".into(),
                reason: format!("{} flags counting {kept} samples for {n} samples", counted.len()),
            });
        }
        let pick = |v: &[f64]| -> Vec<f64> {
            v.chunks_exact(ny)
                .zip(&counted)
                .filter(|(_, c)| **c)
                .flat_map(|(r, _)| r.iter().copied())
                .collect()
        };
        metrics(&outputs, &pick(&y), &pick(&y_hat), n_params, WHITENESS_LAGS)?
    };
    Ok(Comparison {
        experiment: prep.name,
        h: experiment.h(),
        t0: experiment.t0(),
        outputs,
        units,
        y,
        y_hat,
        metrics,
        counted,
        horizon,
    })
}
