//! Weighted linear least squares `min Σ_i w_i (y_i − φ_iᵀθ)²`, streamed: the rows are
//! folded, block by block, into the triangular factor R of the row-weighted augmented
//! matrix `[Φ | y]` (a tall-skinny QR), so no rows × n_θ matrix is ever stored. Standard
//! errors and the parametric error index follow from R (thesis 5.2.1, 5.3 and appendix B).
//! Domain code forms the regressors (for the PMSM: [`crate::pmsm::weighted_least_squares`]).
//!
//! Each block of [`BLOCK`] rows is stacked under the running R and reduced by Householder
//! reflections, one per column: the reflection of column j touches row j of R and the
//! block's rows only. This is Householder QR of the whole matrix with the rows visited in
//! another order, so it is backward stable column by column (Golub & Van Loan 5.2.1): the
//! accuracy is that of a dense QR, with no squared condition number as the normal
//! equations have. Column scaling commutes with the reflections (`R(ΦD) = R(Φ) D`), so the
//! columns are equilibrated afterwards, on R, for the rank check and the solve.
//! Everything runs on the calling thread in a fixed order: the result is bit-identical for
//! any thread count.

use crate::error::{Error, Result};
use multiversion::multiversion;
use nalgebra::DMatrix;

/// Smallest accepted `|R_jj|` of the QR factor of the column-equilibrated regressors (unit
/// column norms): below it, column j is numerically a combination of the columns before
/// it and the estimate is refused as rank deficient.
pub const RANK_TOLERANCE: f64 = 1e-9;

/// Rows per block folded into R by [`StreamedLeastSquares`].
pub const BLOCK: usize = 1024;

/// The solution of [`solve_weighted`] and [`StreamedLeastSquares::solve`].
#[derive(Clone, Debug, PartialEq)]
pub struct LinearSolution {
    /// Estimates θ̂, length n_θ \[units of the regressors' parameters\].
    pub theta: Vec<f64>,
    /// Standard errors `√(σ̂² [(ΦᵀWΦ)⁻¹]_ii)` with `σ̂² = E²/(rows_w − n_θ)` (rows_w: rows
    /// of positive weight), length n_θ; NaN without degrees of freedom.
    pub std_error: Vec<f64>,
    /// Parametric error index `P_i = 100 √(E² [(ΦᵀWΦ)⁻¹]_ii) / |θ̂_i|` \[%\], length n_θ.
    pub error_index_percent: Vec<f64>,
    /// Weighted squared residual `E² = Σ w r²` at θ̂ (from R: the squared norm of the part
    /// of `y` that the columns do not span).
    pub e2: f64,
    /// `(ΦᵀWΦ)⁻¹`, n_θ × n_θ (rows): times `σ̂²` the covariance of θ̂.
    pub inverse: Vec<Vec<f64>>,
    /// Degrees of freedom `rows_w − n_θ` (0 when none).
    pub dof: usize,
}

/// Streamed weighted least squares: push the rows `(φ_i, y_i, √w_i)` one by one, then
/// [`solve`](Self::solve). Memory is `(n_θ + 1) × (BLOCK + n_θ + 1)` numbers whatever the
/// number of rows; the work is about `(n_θ + 1)²` multiply-adds per row.
///
/// Source: Golub & Van Loan, *Matrix Computations*, 4th ed., 5.2.1 (Householder QR),
/// 5.3.3 (QR least squares); Demmel et al., "Communication-optimal parallel and sequential
/// QR and LU factorizations", SIAM J. Sci. Comput. 34(1), 2012 (tall-skinny QR).
#[derive(Clone, Debug)]
pub struct StreamedLeastSquares {
    /// Columns n_θ (without y).
    cols: usize,
    /// Upper triangle of R, `(n_θ + 1)²`, column-major; the last column holds `Qᵀy`.
    r: Vec<f64>,
    /// Pending rows, column-major `BLOCK × (n_θ + 1)`, already weighted.
    block: Vec<f64>,
    /// Rows pending in `block`.
    filled: usize,
    /// Rows pushed with positive weight.
    rows_w: usize,
    /// A row of the wrong length was pushed (reported by `solve`).
    bad_row: Option<usize>,
    /// Rows pushed.
    rows: usize,
}

impl StreamedLeastSquares {
    /// An empty problem of `cols` parameters.
    pub fn new(cols: usize) -> Self {
        let w = cols + 1;
        Self {
            cols,
            r: vec![0.0; w * w],
            block: vec![0.0; BLOCK * w],
            filled: 0,
            rows_w: 0,
            bad_row: None,
            rows: 0,
        }
    }

    /// Number of parameters n_θ.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Rows pushed so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Appends the row `√w (φ, y)`; `phi` has length n_θ (another length is reported by
    /// [`solve`](Self::solve) as an error). No allocation.
    #[inline]
    pub fn push(&mut self, phi: &[f64], y: f64, sqrt_w: f64) {
        if phi.len() != self.cols {
            self.bad_row.get_or_insert(self.rows);
            return;
        }
        // `filled < BLOCK` always; the modulo lets the compiler drop the bounds checks.
        let i = self.filled % BLOCK;
        let mut columns = self.block.chunks_exact_mut(BLOCK);
        // `phi` first: zip then stops without taking the column of y.
        for (p, col) in phi.iter().zip(columns.by_ref()) {
            col[i] = sqrt_w * p;
        }
        if let Some(col) = columns.next() {
            col[i] = sqrt_w * y;
        }
        self.rows += 1;
        if sqrt_w > 0.0 {
            self.rows_w += 1;
        }
        self.filled += 1;
        if self.filled == BLOCK {
            self.fold();
        }
    }

    /// Folds the pending rows into R: one Householder reflection per column of `[R; B]`.
    fn fold(&mut self) {
        let (m, w) = (self.filled, self.cols + 1);
        self.filled = 0;
        if m > 0 {
            fold_block(&mut self.r, &mut self.block, m, w);
        }
    }

    /// `R_ij` of `[Φ | y]` (`j = n_θ` is the column of `y`).
    fn r(&self, i: usize, j: usize) -> f64 {
        if i <= j { self.r[j * (self.cols + 1) + i] } else { 0.0 }
    }

    /// The solution for all n_θ columns, named `names` (length n_θ).
    ///
    /// # Errors
    /// Those of [`solve_leading`](Self::solve_leading).
    pub fn solve(&mut self, names: &[String]) -> Result<LinearSolution> {
        self.solve_leading(names)
    }

    /// The solution of the nested regression of `y` on the first `names.len()` columns
    /// only (the leading block of R is their QR factor; the rest of `Qᵀy` adds to E²).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] for more names than columns or a row of the wrong length;
    /// [`Error::Numerical`] naming the parameter when its column is zero or not finite
    /// after weighting (not excited) or numerically a combination of the earlier ones
    /// ([`RANK_TOLERANCE`]), or when the solution is not finite.
    pub fn solve_leading(&mut self, names: &[String]) -> Result<LinearSolution> {
        self.fold();
        let (cols, all) = (names.len(), self.cols);
        if cols > all || self.bad_row.is_some() {
            return Err(Error::InvalidOption {
                option: "regressors".into(),
                reason: match self.bad_row {
                    Some(row) => format!("row {row} does not have {all} regressor values"),
                    None => format!("{cols} parameter names for {all} regressor columns"),
                },
            });
        }
        let norms: Vec<f64> =
            (0..cols).map(|j| (0..=j).map(|i| self.r(i, j).powi(2)).sum::<f64>().sqrt()).collect();
        if let Some(j) = norms.iter().position(|&n| !(n > 0.0 && n.is_finite())) {
            return Err(Error::Numerical {
                context: "linear least squares".into(),
                reason: format!(
                    "regressor of `{}` is zero or not finite (after weighting): the data do not excite it",
                    names[j]
                ),
            });
        }
        // Column-equilibrated factor: unit column norms.
        let r_mat = DMatrix::from_fn(cols, cols, |i, j| self.r(i, j) / norms[j]);
        if let Some(j) = (0..cols).find(|&j| r_mat[(j, j)].is_nan() || r_mat[(j, j)].abs() < RANK_TOLERANCE) {
            return Err(Error::Numerical {
                context: "linear least squares".into(),
                reason: format!(
                    "rank deficient: the regressor of `{}` is (nearly) a combination of those of `{}` \
                     (|R_jj| = {:.1e} < {RANK_TOLERANCE:e}); the data do not separate these parameters",
                    names[j],
                    names[..j].join("`, `"),
                    r_mat[(j, j)].abs()
                ),
            });
        }
        let singular = || Error::Numerical {
            context: "linear least squares".into(),
            reason: "triangular factor R is singular".into(),
        };
        let qtb = nalgebra::DVector::from_fn(cols, |i, _| self.r(i, all));
        let sol = r_mat.solve_upper_triangular(&qtb).ok_or_else(singular)?;
        let theta: Vec<f64> = (0..cols).map(|j| sol[j] / norms[j]).collect();
        if theta.iter().any(|t| !t.is_finite()) {
            return Err(Error::Numerical {
                context: "linear least squares".into(),
                reason: "solution is not finite".into(),
            });
        }
        let e2: f64 = (cols..=all).map(|i| self.r(i, all).powi(2)).sum();
        // diag((ΦᵀWΦ)⁻¹) = diag(D⁻¹ R⁻¹ R⁻ᵀ D⁻¹): squared row norms of R⁻¹, unscaled.
        let r_inv = r_mat.solve_upper_triangular(&DMatrix::identity(cols, cols)).ok_or_else(singular)?;
        let inv_diag: Vec<f64> = (0..cols).map(|j| r_inv.row(j).norm_squared() / norms[j].powi(2)).collect();
        let inverse: Vec<Vec<f64>> = (0..cols)
            .map(|i| (0..cols).map(|j| r_inv.row(i).dot(&r_inv.row(j)) / (norms[i] * norms[j])).collect())
            .collect();
        let rows_w = self.rows_w;
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
}

/// `Σ a_i b_i` in eight fixed lanes (vectorisable, and the same order on every machine).
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    let mut s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// Solves the weighted least-squares problem with regressors `phi` (rows × n_θ,
/// row-major, n_θ = `names.len()`), observations `y` (length rows) and square-root row
/// weights `sqrt_w` (length rows, ≥ 0), by [`StreamedLeastSquares`].
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
    let mut ls = StreamedLeastSquares::new(cols);
    if cols == 0 {
        return ls.solve(names);
    }
    for ((row, yi), w) in phi.chunks_exact(cols).zip(y).zip(sqrt_w) {
        ls.push(row, *yi, *w);
    }
    ls.solve(names)
}

/// [`StreamedLeastSquares::fold`] of the m pending rows of `block` (column-major, BLOCK
/// rows a column, w = n_θ + 1 columns) into `r` (w × w): one Householder reflection per
/// column of `[R; B]`. Compiled for AVX-512 and AVX2 as well and chosen at run time: the
/// same operations in the same order ([`dot`]'s eight fixed lanes), so the same numbers.
#[multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn fold_block(r: &mut [f64], block: &mut [f64], m: usize, w: usize) {
    for j in 0..w {
        let (head, tail) = block.split_at_mut((j + 1) * BLOCK);
        let x = &head[j * BLOCK..j * BLOCK + m];
        let sigma = dot(x, x);
        if sigma == 0.0 {
            continue;
        }
        let x0 = r[j * w + j];
        let norm = (x0 * x0 + sigma).sqrt();
        let beta = if x0 >= 0.0 { -norm } else { norm };
        // H = I − τ v vᵀ with v = [1; x / v0] maps [x0; x] to [β; 0].
        let v0 = x0 - beta;
        let tau = (beta - x0) / beta;
        r[j * w + j] = beta;
        for c in j + 1..w {
            let col = &mut tail[(c - j - 1) * BLOCK..(c - j - 1) * BLOCK + m];
            let t = tau * (r[c * w + j] + dot(x, col) / v0);
            r[c * w + j] -= t;
            let s = t / v0;
            for (b, a) in col.iter_mut().zip(x) {
                *b -= s * a;
            }
        }
    }
}
