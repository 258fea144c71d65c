//! The damped solve of an arrowhead system by the Schur complement: each block by a small
//! Cholesky, the reduced shared system by `faer`'s dense Cholesky (LLᵀ).

use super::Arrowhead;
use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use nalgebra::{DMatrix, DVector};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Where the elimination of an arrowhead system failed: the matrix is not positive
/// definite there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Singular {
    /// The block whose own matrix `D_b` (with its damping) has no Cholesky factor, or
    /// `None` for the reduced shared system (the Schur complement).
    pub block: Option<usize>,
    /// The column (index in 0..n) at whose pivot the factorisation failed; for the reduced
    /// system, its first shared column.
    pub column: usize,
}

impl std::fmt::Display for Singular {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.block {
            Some(b) => write!(f, "block {b} is not positive definite at column {}", self.column),
            None => write!(f, "the reduced shared system is not positive definite"),
        }
    }
}

static SOLVES: AtomicU64 = AtomicU64::new(0);
static TOTAL_NS: AtomicU64 = AtomicU64::new(0);
static REDUCED_NS: AtomicU64 = AtomicU64::new(0);

/// Time spent in [`Arrowhead::damped_solve`] since the process started (a counter every
/// call adds to, on any thread): for the share of a fit's time that the structured solve
/// takes, read before and after the fit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveTiming {
    /// Number of solves.
    pub solves: u64,
    /// Time in the solves, elimination of the blocks included \[s\].
    pub total_s: f64,
    /// Of it, the reduced shared system: forming nothing, only `faer`'s factorisation and
    /// solve \[s\].
    pub reduced_s: f64,
}

/// The counters of [`SolveTiming`] now.
pub fn solve_timing() -> SolveTiming {
    SolveTiming {
        solves: SOLVES.load(Ordering::Relaxed),
        total_s: TOTAL_NS.load(Ordering::Relaxed) as f64 * 1e-9,
        reduced_s: REDUCED_NS.load(Ordering::Relaxed) as f64 * 1e-9,
    }
}

/// In-place lower Cholesky factor of a small symmetric matrix (the lower triangle is
/// read); the failing pivot's index when it is not positive definite.
pub(super) fn small_cholesky(a: &mut DMatrix<f64>) -> Result<(), usize> {
    let n = a.nrows();
    for j in 0..n {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= a[(j, k)] * a[(j, k)];
        }
        if !(d > 0.0 && d.is_finite()) {
            return Err(j);
        }
        let d = d.sqrt();
        a[(j, j)] = d;
        for i in j + 1..n {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= a[(i, k)] * a[(j, k)];
            }
            a[(i, j)] = s / d;
        }
        for i in 0..j {
            a[(i, j)] = 0.0;
        }
    }
    Ok(())
}

/// Solves `L Lᵀ X = B` in place (L from [`small_cholesky`]).
pub(super) fn small_solve(l: &DMatrix<f64>, b: &mut DMatrix<f64>) {
    let n = l.nrows();
    for c in 0..b.ncols() {
        for i in 0..n {
            let mut s = b[(i, c)];
            for k in 0..i {
                s -= l[(i, k)] * b[(k, c)];
            }
            b[(i, c)] = s / l[(i, i)];
        }
        for i in (0..n).rev() {
            let mut s = b[(i, c)];
            for k in i + 1..n {
                s -= l[(k, i)] * b[(k, c)];
            }
            b[(i, c)] = s / l[(i, i)];
        }
    }
}

/// `faer`'s Cholesky of a dense symmetric matrix, `None` when not positive definite.
pub(super) fn faer_llt(a: &DMatrix<f64>) -> Option<faer::linalg::solvers::Llt<f64>> {
    let m = Mat::<f64>::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)]);
    m.llt(Side::Lower).ok()
}

impl Arrowhead {
    /// Solves `(A + λ diag(d)) δ = g` (d, g of length n; λ ≥ 0) by eliminating every block
    /// (`D̃_b = D_b + λ diag(d_b)`, a small Cholesky each) and solving the reduced system
    /// `(F̃ − Σ_b C_bᵀ D̃_b⁻¹ C_b) δ_s = g_s − Σ_b C_bᵀ D̃_b⁻¹ g_b` (`p_s × p_s`) with
    /// `faer`'s Cholesky; then `δ_b = D̃_b⁻¹ (g_b − C_b δ_s)`. Work `O(N p_b²(p_b + p_s) +
    /// p_s³)`, memory `O(N p_b p_s + p_s²)`.
    ///
    /// # Errors
    /// [`Singular`] naming the block and column where the damped matrix is not positive
    /// definite (the dense Cholesky fails there too: the system is the same).
    ///
    /// # Panics
    /// If d or g is not of length n.
    pub fn damped_solve(
        &self,
        d: &DVector<f64>,
        lambda: f64,
        g: &DVector<f64>,
    ) -> Result<DVector<f64>, Singular> {
        let t0 = Instant::now();
        let out = self.schur_solve(d, lambda, g);
        SOLVES.fetch_add(1, Ordering::Relaxed);
        TOTAL_NS.fetch_add(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
        out
    }

    fn schur_solve(&self, d: &DVector<f64>, lambda: f64, g: &DVector<f64>) -> Result<DVector<f64>, Singular> {
        let l = &self.layout;
        assert!(
            d.len() == l.n() && g.len() == l.n(),
            "damped solve of {} with {} and {}",
            l.n(),
            d.len(),
            g.len()
        );
        let ps = l.shared.len();
        let mut reduced = self.shared.clone();
        for (i, &c) in l.shared.iter().enumerate() {
            reduced[(i, i)] += lambda * d[c];
        }
        let mut rhs = DVector::from_iterator(ps, l.shared.iter().map(|&c| g[c]));
        // Per block: its factor and D̃⁻¹[C g_b] (p_b × (p_s + 1)).
        let mut eliminated = Vec::with_capacity(l.blocks.len());
        for (b, cols) in l.blocks.iter().enumerate() {
            if cols.is_empty() {
                eliminated.push(None);
                continue;
            }
            let mut f = self.own[b].clone();
            for (i, &c) in cols.iter().enumerate() {
                f[(i, i)] += lambda * d[c];
            }
            small_cholesky(&mut f).map_err(|i| Singular { block: Some(b), column: cols[i] })?;
            let mut y = DMatrix::zeros(cols.len(), ps + 1);
            y.columns_mut(0, ps).copy_from(&self.coupling[b]);
            for (i, &c) in cols.iter().enumerate() {
                y[(i, ps)] = g[c];
            }
            small_solve(&f, &mut y);
            let cb = &self.coupling[b];
            reduced -= cb.tr_mul(&y.columns(0, ps));
            rhs -= cb.tr_mul(&y.column(ps));
            eliminated.push(Some(f));
        }
        let t1 = Instant::now();
        let delta_s = if ps == 0 {
            DVector::zeros(0)
        } else {
            let singular = Singular { block: None, column: l.shared[0] };
            let llt = faer_llt(&reduced).ok_or(singular)?;
            let mut x = Mat::<f64>::from_fn(ps, 1, |i, _| rhs[i]);
            llt.solve_in_place(&mut x);
            DVector::from_fn(ps, |i, _| x[(i, 0)])
        };
        REDUCED_NS.fetch_add(t1.elapsed().as_nanos() as u64, Ordering::Relaxed);
        let mut delta = DVector::zeros(l.n());
        for (&c, v) in l.shared.iter().zip(delta_s.iter()) {
            delta[c] = *v;
        }
        for ((cols, f), cb) in l.blocks.iter().zip(&eliminated).zip(&self.coupling) {
            let Some(f) = f else { continue };
            let gb = DVector::from_iterator(cols.len(), cols.iter().map(|&c| g[c]));
            let mut y = DMatrix::from_column_slice(cols.len(), 1, (gb - cb * &delta_s).as_slice());
            small_solve(f, &mut y);
            for (i, &c) in cols.iter().enumerate() {
                delta[c] = y[(i, 0)];
            }
        }
        Ok(delta)
    }
}
