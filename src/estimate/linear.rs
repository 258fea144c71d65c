//! Linear least squares on the dq voltage equations (thesis section 5.2.1, MODEL.md §5).
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
//! Solved by a QR decomposition of the tall regressor matrix (faer). With noisy currents
//! the derivative column is errors-in-variables and `L` comes out low: use the result as
//! the start of the prediction-error fit, not as the answer.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::spm::SQRT_2_3;
use faer::prelude::*;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Which machine the regression assumes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum MotorKind {
    /// Surface magnets, `θ = (r_s, l_s, k_e)`.
    #[default]
    Spm,
    /// Interior magnets, `θ = (r_s, l_d, l_q, k_e)`.
    Ipm,
}

impl MotorKind {
    /// Parameter names in order.
    pub fn parameter_names(self) -> &'static [&'static str] {
        match self {
            Self::Spm => &["r_s", "l_s", "k_e"],
            Self::Ipm => &["r_s", "l_d", "l_q", "k_e"],
        }
    }
}

/// Result of the linear least-squares estimate.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LinearEstimate {
    /// Parameter names, e.g. `["r_s", "l_s", "k_e"]`.
    pub names: Vec<String>,
    /// Estimates θ̂ in SI units (Ω, H, V s/rad), length n_θ.
    pub theta: Vec<f64>,
    /// Parametric error index `P_i = 100 √(E² [(ΦᵀΦ)⁻¹]_ii) / |θ̂_i|` [%] (thesis 5.3).
    pub error_index_percent: Vec<f64>,
    /// RMS equation residual of the d and q rows [V], length 2.
    pub rms_residual: [f64; 2],
    /// Number of regression rows.
    pub rows: usize,
}

/// Regressor matrix Φ (rows × n_θ, row-major) and voltages y of one experiment.
///
/// Rows alternate d, q for every interval `k = 0..N−2`.
pub fn regressors(e: &Experiment, kind: MotorKind) -> (Vec<f64>, Vec<f64>) {
    let (h, np) = (e.h(), f64::from(e.n_p()));
    let (id, iq, wm) = (e.i_d(), e.i_q(), e.w_m());
    let n = e.len() - 1;
    let cols = kind.parameter_names().len();
    let mut phi = Vec::with_capacity(2 * n * cols);
    let mut y = Vec::with_capacity(2 * n);
    for k in 0..n {
        let (idm, iqm) = (0.5 * (id[k] + id[k + 1]), 0.5 * (iq[k] + iq[k + 1]));
        let (did, diq) = ((id[k + 1] - id[k]) / h, (iq[k + 1] - iq[k]) / h);
        let w_m = 0.5 * (wm[k] + wm[k + 1]);
        let w_e = np * w_m;
        match kind {
            MotorKind::Spm => {
                phi.extend_from_slice(&[idm, did - w_e * iqm, 0.0]);
                phi.extend_from_slice(&[iqm, diq + w_e * idm, SQRT_2_3 * w_m]);
            }
            MotorKind::Ipm => {
                phi.extend_from_slice(&[idm, did, -w_e * iqm, 0.0]);
                phi.extend_from_slice(&[iqm, w_e * idm, diq, SQRT_2_3 * w_m]);
            }
        }
        y.push(e.u_d()[k]);
        y.push(e.u_q()[k]);
    }
    (phi, y)
}

/// Least-squares estimate of θ from one or more experiments of one motor.
///
/// # Errors
/// [`Error::InvalidOption`] for an empty experiment list; [`Error::Numerical`] when the
/// regressors are rank deficient (e.g. no speed: K_e not identifiable) or the solution is
/// not finite.
///
/// # Example
/// ```no_run
/// use greybox::estimate::linear::{least_squares, MotorKind};
/// # fn main() -> greybox::Result<()> {
/// let e = greybox::read_csv("data/sample.csv.gz", 4, &Default::default())?;
/// let ls = least_squares(&[e], MotorKind::Spm)?;
/// println!("R_s = {:.4} Ω", ls.theta[0]);
/// # Ok(()) }
/// ```
pub fn least_squares(experiments: &[Experiment], kind: MotorKind) -> Result<LinearEstimate> {
    if experiments.is_empty() {
        return Err(Error::InvalidOption {
            option: "experiments".into(),
            reason: "no experiment given".into(),
        });
    }
    let cols = kind.parameter_names().len();
    let (mut phi, mut y) = (Vec::new(), Vec::new());
    for e in experiments {
        let (p, v) = regressors(e, kind);
        phi.extend(p);
        y.extend(v);
    }
    let rows = y.len();
    // Column equilibration keeps the QR well scaled (columns differ by ~10⁴).
    let norms: Vec<f64> =
        (0..cols).map(|j| (0..rows).map(|i| phi[i * cols + j].powi(2)).sum::<f64>().sqrt()).collect();
    if let Some(j) = norms.iter().position(|&n| !(n > 0.0 && n.is_finite())) {
        return Err(Error::Numerical {
            context: "linear least squares".into(),
            reason: format!(
                "regressor of `{}` is zero or not finite: the data do not excite it",
                kind.parameter_names()[j]
            ),
        });
    }
    let a = Mat::<f64>::from_fn(rows, cols, |i, j| phi[i * cols + j] / norms[j]);
    let b = Mat::<f64>::from_fn(rows, 1, |i, _| y[i]);
    let sol = a.qr().solve_lstsq(&b);
    let theta: Vec<f64> = (0..cols).map(|j| sol[(j, 0)] / norms[j]).collect();
    if theta.iter().any(|t| !t.is_finite()) {
        return Err(Error::Numerical {
            context: "linear least squares".into(),
            reason: "solution is not finite".into(),
        });
    }
    let mut sse = [0.0; 2];
    let mut gram = DMatrix::<f64>::zeros(cols, cols);
    for i in 0..rows {
        let row = &phi[i * cols..(i + 1) * cols];
        let r = y[i] - row.iter().zip(&theta).map(|(a, b)| a * b).sum::<f64>();
        sse[i % 2] += r * r;
        for a in 0..cols {
            for b in 0..cols {
                gram[(a, b)] += row[a] * row[b] / (norms[a] * norms[b]);
            }
        }
    }
    let e2 = sse[0] + sse[1];
    let inv_diag = covariance_diagonal(&gram)
        .map(|d| DVector::from_iterator(cols, d.iter().enumerate().map(|(j, v)| v / (norms[j] * norms[j]))));
    let error_index_percent = (0..cols)
        .map(|j| match &inv_diag {
            Some(d) => 100.0 * (e2 * d[j]).sqrt() / theta[j].abs(),
            None => f64::INFINITY,
        })
        .collect();
    Ok(LinearEstimate {
        names: kind.parameter_names().iter().map(|s| s.to_string()).collect(),
        theta,
        error_index_percent,
        rms_residual: [(sse[0] / (rows / 2) as f64).sqrt(), (sse[1] / (rows / 2) as f64).sqrt()],
        rows,
    })
}

/// Diagonal of `G⁻¹` for a symmetric positive definite G, via Cholesky; `None` if singular.
pub(crate) fn covariance_diagonal(g: &DMatrix<f64>) -> Option<DVector<f64>> {
    let inv = g.clone().cholesky()?.inverse();
    Some(inv.diagonal())
}
