//! Identifiability diagnostics: how well the data determine each parameter, and what to
//! do when they do not.
//!
//! From the information matrix at the estimate in relative units,
//! `M = diag(θ̂) JᵀWJ diag(θ̂)` (the sensitivity to a relative change of each parameter),
//! the singular values and condition number say how many parameter combinations the
//! data pin down; the parametric error index (thesis 5.3) and the correlation matrix name
//! the parameters that are poorly determined or confounded. What data would help is the
//! model's knowledge ([`crate::model::GreyBoxModel::advice`]); this module only asks.

use serde::{Deserialize, Serialize};

/// Thresholds above which a parameter is reported as poorly determined or confounded.
///
/// Defaults are conventions, not laws: an error index of 10 % (the change of a parameter
/// that doubles the residual energy, thesis 5.3), |ρ| = 0.95 (a common collinearity
/// warning level, Belsley, Kuh & Welsch, *Regression Diagnostics*, 1980), and a condition
/// number of 10⁸ (half the digits of double precision lost in the normal equations).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DiagnosticThresholds {
    /// Parametric error index \[%\] above which a parameter is poorly determined.
    pub error_index_percent: f64,
    /// |correlation| above which two parameters are reported as confounded.
    pub correlation: f64,
    /// Condition number of the relative information matrix above which it is ill-conditioned.
    pub condition_number: f64,
}

impl Default for DiagnosticThresholds {
    fn default() -> Self {
        Self { error_index_percent: 10.0, correlation: 0.95, condition_number: 1e8 }
    }
}

/// A parameter whose error index exceeds the threshold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoorlyDetermined {
    /// Parameter name (with `[experiment]` for per-experiment copies).
    pub name: String,
    /// Its error index \[%\].
    pub error_index_percent: f64,
}

/// A pair of strongly correlated parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Correlated {
    /// First parameter.
    pub a: String,
    /// Second parameter.
    pub b: String,
    /// Their estimated correlation.
    pub correlation: f64,
}

/// Diagnostics of a fit (JSON key `diagnostics`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Diagnostics {
    /// Singular values of the relative information matrix, descending (free model parameters).
    pub singular_values: Vec<f64>,
    /// Ratio of the largest to the smallest singular value (∞ when singular).
    pub condition_number: f64,
    /// Parameters whose error index exceeds the threshold.
    pub poorly_determined: Vec<PoorlyDetermined>,
    /// Parameter pairs whose |correlation| exceeds the threshold.
    pub correlated: Vec<Correlated>,
    /// Plain-language advice.
    pub advice: Vec<String>,
}

/// Builds the diagnostics from the relative information matrix `m` (n × n, symmetric),
/// the parameter names (length n), error indices \[%\] (length n) and correlation matrix
/// (n × n) of the same parameters; shorter inputs are read as far as they go.
///
/// `advice(name)` and `pair_advice(a, b)` give the domain's advice for a poorly determined
/// parameter and a correlated pair (`None`: a generic text).
pub fn diagnose(
    m: &nalgebra::DMatrix<f64>,
    names: &[String],
    error_index: &[f64],
    correlation: &[Vec<f64>],
    thresholds: &DiagnosticThresholds,
    advice: &dyn Fn(&str) -> Option<String>,
    pair_advice: &dyn Fn(&str, &str) -> Option<String>,
) -> Diagnostics {
    let mut singular_values: Vec<f64> = if m.iter().all(|v| v.is_finite()) && m.nrows() > 0 {
        m.clone().svd(false, false).singular_values.iter().copied().collect()
    } else {
        Vec::new()
    };
    singular_values.sort_by(|a, b| b.total_cmp(a));
    let condition_number = match (singular_values.first(), singular_values.last()) {
        (Some(&hi), Some(&lo)) if lo > 0.0 => hi / lo,
        _ => f64::INFINITY,
    };
    let poorly_determined: Vec<PoorlyDetermined> = names
        .iter()
        .zip(error_index)
        .filter(|(_, e)| e.is_nan() || **e > thresholds.error_index_percent)
        .map(|(n, e)| PoorlyDetermined { name: n.clone(), error_index_percent: *e })
        .collect();
    let mut correlated = Vec::new();
    for a in 0..names.len() {
        for b in a + 1..names.len() {
            let r = correlation.get(a).and_then(|row| row.get(b)).copied().unwrap_or(f64::NAN);
            if r.abs() > thresholds.correlation {
                correlated.push(Correlated { a: names[a].clone(), b: names[b].clone(), correlation: r });
            }
        }
    }
    let mut texts: Vec<String> = poorly_determined
        .iter()
        .map(|p| {
            let a = advice(&p.name).unwrap_or_else(|| {
                format!("{} poorly determined: the data carry little information about it", p.name)
            });
            format!("{a} (error index {:.3} %)", p.error_index_percent)
        })
        .collect();
    for c in &correlated {
        texts.push(format!(
            "{} and {} are strongly correlated (ρ = {:+.3}): the data hardly separate them; {}",
            c.a,
            c.b,
            c.correlation,
            pair_advice(&c.a, &c.b)
                .unwrap_or_else(|| "add excitation that moves them differently, or fix one of them".into())
        ));
    }
    let mut advice = texts;
    if !names.is_empty() && condition_number > thresholds.condition_number {
        advice.push(format!(
            "the information matrix is ill-conditioned (condition number {condition_number:.2e}): \
             some parameter combination is not determined; fix a parameter or add excitation"
        ));
    }
    Diagnostics { singular_values, condition_number, poorly_determined, correlated, advice }
}
