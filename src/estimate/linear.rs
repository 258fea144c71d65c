//! Weighted linear least squares `min Σ_i w_i (y_i − φ_iᵀθ)²` by a QR decomposition of
//! the column-equilibrated, row-weighted regressor matrix (faer), with standard errors and
//! the parametric error index (thesis 5.2.1, 5.3 and appendix B). Domain code forms the
//! regressors (for the PMSM: [`crate::pmsm::weighted_least_squares`]).

use crate::error::{Error, Result};
use faer::prelude::*;
use nalgebra::DMatrix;

/// Smallest accepted `|R_jj|` of the QR factor of the column-equilibrated regressors (unit
/// column norms): below it, column j is numerically a combination of the columns before
/// it and the estimate is refused as rank deficient.
pub const RANK_TOLERANCE: f64 = 1e-9;

/// The solution of [`solve_weighted`].
#[derive(Clone, Debug, PartialEq)]
pub struct LinearSolution {
    /// Estimates θ̂, length n_θ [units of the regressors' parameters].
    pub theta: Vec<f64>,
    /// Standard errors `√(σ̂² [(ΦᵀWΦ)⁻¹]_ii)` with `σ̂² = E²/(rows_w − n_θ)` (rows_w: rows
    /// of positive weight), length n_θ; NaN without degrees of freedom.
    pub std_error: Vec<f64>,
    /// Parametric error index `P_i = 100 √(E² [(ΦᵀWΦ)⁻¹]_ii) / |θ̂_i|` [%], length n_θ.
    pub error_index_percent: Vec<f64>,
    /// Weighted squared residual `E² = Σ w r²` at θ̂.
    pub e2: f64,
    /// `(ΦᵀWΦ)⁻¹`, n_θ × n_θ (rows): times `σ̂²` the covariance of θ̂.
    pub inverse: Vec<Vec<f64>>,
    /// Degrees of freedom `rows_w − n_θ` (0 when none).
    pub dof: usize,
}

/// Solves the weighted least-squares problem with regressors `phi` (rows × n_θ,
/// row-major, n_θ = `names.len()`), observations `y` (length rows) and square-root row
/// weights `sqrt_w` (length rows, ≥ 0).
///
/// # Errors
/// [`Error::InvalidOption`] for inconsistent lengths; [`Error::Numerical`] naming the
/// parameter when its column is zero or not finite after weighting (not excited) or
/// numerically a combination of the earlier ones ([`RANK_TOLERANCE`]), or when the
/// solution is not finite.
///
/// Source: Golub & Van Loan, *Matrix Computations*, 4th ed., 5.3 (QR least squares);
/// thesis 5.3 and appendix B (error index).
pub fn solve_weighted(names: &[String], phi: &[f64], y: &[f64], sqrt_w: &[f64]) -> Result<LinearSolution> {
    let (rows, cols) = (y.len(), names.len());
    if phi.len() != rows * cols || sqrt_w.len() != rows {
        return Err(Error::InvalidOption {
            option: "regressors".into(),
            reason: format!(
                "{} regressor values, {} weights for {rows} rows of {cols} parameters",
                phi.len(),
                sqrt_w.len()
            ),
        });
    }
    let sw = sqrt_w;
    // Column equilibration keeps the QR well scaled (columns may differ by ~10⁴).
    let norms: Vec<f64> = (0..cols)
        .map(|j| (0..rows).map(|i| (sw[i] * phi[i * cols + j]).powi(2)).sum::<f64>().sqrt())
        .collect();
    if let Some(j) = norms.iter().position(|&n| !(n > 0.0 && n.is_finite())) {
        return Err(Error::Numerical {
            context: "linear least squares".into(),
            reason: format!(
                "regressor of `{}` is zero or not finite (after weighting): the data do not excite it",
                names[j]
            ),
        });
    }
    // QR of the augmented matrix [A | b] on one thread (bit-identical results for any thread
    // count): its triangle holds R and Qᵀb, so θ = R⁻¹ (Qᵀb)_{0..n}.
    let mut ab = Mat::<f64>::from_fn(rows, cols + 1, |i, j| {
        if j < cols { sw[i] * phi[i * cols + j] / norms[j] } else { sw[i] * y[i] }
    });
    let size = rows.min(cols + 1);
    let block = faer::linalg::qr::no_pivoting::factor::recommended_block_size::<f64>(rows, cols + 1);
    let mut householder = Mat::<f64>::zeros(block, size);
    let scratch = faer::linalg::qr::no_pivoting::factor::qr_in_place_scratch::<f64>(
        rows,
        cols + 1,
        block,
        Par::Seq,
        Default::default(),
    );
    faer::linalg::qr::no_pivoting::factor::qr_in_place(
        ab.as_mut(),
        householder.as_mut(),
        Par::Seq,
        faer::dyn_stack::MemStack::new(&mut faer::dyn_stack::MemBuffer::new(scratch)),
        Default::default(),
    );
    let r = |i: usize, j: usize| if i <= j && i < rows { ab[(i, j)] } else { 0.0 };
    if let Some(j) = (0..cols).find(|&j| r(j, j).is_nan() || r(j, j).abs() < RANK_TOLERANCE) {
        return Err(Error::Numerical {
            context: "linear least squares".into(),
            reason: format!(
                "rank deficient: the regressor of `{}` is (nearly) a combination of those of `{}` \
                 (|R_jj| = {:.1e} < {RANK_TOLERANCE:e}); the data do not separate these parameters",
                names[j],
                names[..j].join("`, `"),
                r(j, j).abs()
            ),
        });
    }
    let r_mat = DMatrix::from_fn(cols, cols, r);
    let qtb = nalgebra::DVector::from_fn(cols, |i, _| r(i, cols));
    let sol = r_mat.solve_upper_triangular(&qtb).ok_or_else(|| Error::Numerical {
        context: "linear least squares".into(),
        reason: "triangular factor R is singular".into(),
    })?;
    let theta: Vec<f64> = (0..cols).map(|j| sol[j] / norms[j]).collect();
    if theta.iter().any(|t| !t.is_finite()) {
        return Err(Error::Numerical {
            context: "linear least squares".into(),
            reason: "solution is not finite".into(),
        });
    }
    let mut e2 = 0.0;
    for i in 0..rows {
        let row = &phi[i * cols..(i + 1) * cols];
        let res = y[i] - row.iter().zip(&theta).map(|(a, b)| a * b).sum::<f64>();
        e2 += (sw[i] * res).powi(2);
    }
    // diag((ΦᵀWΦ)⁻¹) = diag(D⁻¹ R⁻¹ R⁻ᵀ D⁻¹): squared row norms of R⁻¹, unscaled.
    let r_inv =
        r_mat.solve_upper_triangular(&DMatrix::identity(cols, cols)).ok_or_else(|| Error::Numerical {
            context: "linear least squares".into(),
            reason: "triangular factor R is singular".into(),
        })?;
    let inv_diag: Vec<f64> = (0..cols).map(|j| r_inv.row(j).norm_squared() / norms[j].powi(2)).collect();
    let inverse: Vec<Vec<f64>> = (0..cols)
        .map(|i| (0..cols).map(|j| r_inv.row(i).dot(&r_inv.row(j)) / (norms[i] * norms[j])).collect())
        .collect();
    let rows_w = sw.iter().filter(|w| **w > 0.0).count();
    let sigma2 = if rows_w > cols { e2 / (rows_w - cols) as f64 } else { f64::NAN };
    Ok(LinearSolution {
        std_error: inv_diag.iter().map(|d| (sigma2 * d).sqrt()).collect(),
        error_index_percent: inv_diag
            .iter()
            .zip(&theta)
            .map(|(d, t)| 100.0 * (e2 * d).sqrt() / t.abs())
            .collect(),
        theta,
        e2,
        inverse,
        dof: rows_w.saturating_sub(cols),
    })
}
