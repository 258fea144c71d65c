//! Entries of the inverse of an arrowhead matrix and of a sandwich `A⁻¹ B A⁻¹`, from the
//! blocks' inverses and the inverse of the Schur complement, without forming either.
//!
//! With `P = blockdiag(D_b⁻¹, 0)`, `W` the n × p_s matrix whose block rows are
//! `−D_b⁻¹ C_b` and whose shared rows are the identity, and `Σ = F − Σ_b C_bᵀ D_b⁻¹ C_b`:
//! `A⁻¹ = P + W Σ⁻¹ Wᵀ`. For a symmetric B of the same structure, with `G = B W`:
//! `A⁻¹ B A⁻¹ = P B P + P G Σ⁻¹ Wᵀ + W Σ⁻¹ Gᵀ P + W Σ⁻¹ (Wᵀ G) Σ⁻¹ Wᵀ`, and `P B P` is
//! block diagonal. Each entry costs `O(p_s²)`.

use super::solve::{faer_llt, small_cholesky, small_solve};
use super::{ArrowLayout, Arrowhead, Singular};
use faer::linalg::solvers::DenseSolveCore;
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// `A⁻¹` of a symmetric positive semi-definite arrowhead matrix on the columns with a
/// positive diagonal (those with a zero or NaN one are "unseen": ∞ on the diagonal, 0
/// elsewhere, as a dense inverse on the support).
#[derive(Clone, Debug)]
pub struct ArrowInverse {
    layout: Arc<ArrowLayout>,
    /// D_b⁻¹.
    own_inv: Vec<DMatrix<f64>>,
    /// −D_b⁻¹ C_b (p_b × p_s).
    w: Vec<DMatrix<f64>>,
    /// Σ⁻¹ (p_s × p_s), the inverse of the Schur complement.
    sigma_inv: DMatrix<f64>,
    unseen: Vec<bool>,
}

/// Terms `Σ_r c_r x_r y_rᵀ` (x, y of length n): the part of a matrix outside the arrowhead
/// structure (a rank-two correction of a batch-means meat).
pub type LowRank = Vec<(f64, DVector<f64>, DVector<f64>)>;

/// The sandwich `A⁻¹ (B + Σ_r c_r x_r y_rᵀ) A⁻¹` entry by entry.
#[derive(Clone, Debug)]
pub struct Sandwich {
    inv: ArrowInverse,
    /// `D_b⁻¹ B_bb D_b⁻¹`.
    pbp: Vec<DMatrix<f64>>,
    /// Rows of `P G Σ⁻¹` (block rows; 0 for shared rows).
    a: Vec<DMatrix<f64>>,
    /// `M = Σ⁻¹ Wᵀ G Σ⁻¹`.
    m: DMatrix<f64>,
    /// `c_r`, `A⁻¹ x_r`, `A⁻¹ y_r`.
    low: Vec<(f64, DVector<f64>, DVector<f64>)>,
}

impl Arrowhead {
    /// Its inverse on the support (see [`ArrowInverse`]).
    ///
    /// # Errors
    /// [`Singular`] naming the block and column where a block, or the Schur complement,
    /// is not positive definite on the support.
    pub fn inverse_on_support(&self) -> Result<ArrowInverse, Singular> {
        let l = &self.layout;
        let unseen: Vec<bool> = (0..l.n())
            .map(|g| {
                let d = self.get(g, g);
                d.is_nan() || d <= 0.0
            })
            .collect();
        let a = self.with_identity_at(&unseen);
        let ps = l.shared.len();
        let mut sigma = a.shared.clone();
        let (mut own_inv, mut w) = (Vec::new(), Vec::new());
        for (b, cols) in l.blocks.iter().enumerate() {
            let mut f = a.own[b].clone();
            small_cholesky(&mut f).map_err(|i| Singular { block: Some(b), column: cols[i] })?;
            let mut inv = DMatrix::identity(cols.len(), cols.len());
            small_solve(&f, &mut inv);
            let wb = -(&inv * &a.coupling[b]);
            sigma += a.coupling[b].tr_mul(&wb);
            own_inv.push(inv);
            w.push(wb);
        }
        let sigma_inv = if ps == 0 {
            DMatrix::zeros(0, 0)
        } else {
            // The reported covariance's one explicit inverse (p_s × p_s).
            let singular = Singular { block: None, column: l.shared[0] };
            let inv = faer_llt(&sigma).ok_or(singular)?.inverse();
            DMatrix::from_fn(ps, ps, |i, j| inv[(i, j)])
        };
        Ok(ArrowInverse { layout: Arc::clone(l), own_inv, w, sigma_inv, unseen })
    }
}

impl ArrowInverse {
    /// Row g of W (length p_s).
    fn w_row(&self, g: usize) -> DVector<f64> {
        let l = &self.layout;
        match l.owner[g] {
            None => {
                let mut e = DVector::zeros(l.shared.len());
                e[l.pos[g]] = 1.0;
                e
            }
            Some(b) => self.w[b].row(l.pos[g]).transpose(),
        }
    }

    /// Entry (g, h) of `A⁻¹`.
    ///
    /// # Panics
    /// If g or h is ≥ n.
    pub fn entry(&self, g: usize, h: usize) -> f64 {
        if self.unseen[g] || self.unseen[h] {
            return if g == h { f64::INFINITY } else { 0.0 };
        }
        let l = &self.layout;
        let p = match (l.owner[g], l.owner[h]) {
            (Some(a), Some(b)) if a == b => self.own_inv[a][(l.pos[g], l.pos[h])],
            _ => 0.0,
        };
        p + self.w_row(g).dot(&(&self.sigma_inv * self.w_row(h)))
    }

    /// `A⁻¹ x` (length n) with the unseen entries of x and of the result 0.
    ///
    /// # Panics
    /// If x is not of length n.
    pub fn apply(&self, x: &DVector<f64>) -> DVector<f64> {
        let l = &self.layout;
        let x = DVector::from_fn(l.n(), |g, _| if self.unseen[g] { 0.0 } else { x[g] });
        // Wᵀ x, then Σ⁻¹ of it.
        let mut wx = DVector::from_iterator(l.shared.len(), l.shared.iter().map(|&g| x[g]));
        for (b, cols) in l.blocks.iter().enumerate() {
            let xb = DVector::from_iterator(cols.len(), cols.iter().map(|&g| x[g]));
            wx += self.w[b].tr_mul(&xb);
        }
        let s = &self.sigma_inv * wx;
        let mut y = DVector::zeros(l.n());
        for (&g, v) in l.shared.iter().zip(s.iter()) {
            y[g] = *v;
        }
        for (b, cols) in l.blocks.iter().enumerate() {
            let xb = DVector::from_iterator(cols.len(), cols.iter().map(|&g| x[g]));
            let yb = &self.own_inv[b] * xb + &self.w[b] * &s;
            for (&g, v) in cols.iter().zip(yb.iter()) {
                y[g] = *v;
            }
        }
        for (g, v) in y.iter_mut().enumerate() {
            if self.unseen[g] {
                *v = 0.0;
            }
        }
        y
    }

    /// The sandwich `A⁻¹ (B + Σ_r c_r x_r y_rᵀ) A⁻¹` (B of the same layout).
    pub fn sandwich(&self, b: &Arrowhead, low: &LowRank) -> Sandwich {
        let l = &self.layout;
        let ps = l.shared.len();
        // G = B W: shared rows F + Σ_b C_bᵀ W_b, block rows C_b + D_b W_b.
        let mut g_shared = b.shared.clone();
        let mut g_own = Vec::with_capacity(l.blocks.len());
        for bb in 0..l.blocks.len() {
            g_shared += b.coupling[bb].tr_mul(&self.w[bb]);
            g_own.push(&b.coupling[bb] + &b.own[bb] * &self.w[bb]);
        }
        // Wᵀ G.
        let mut wg = g_shared.clone();
        for (wb, gb) in self.w.iter().zip(&g_own) {
            wg += wb.tr_mul(gb);
        }
        let m = &self.sigma_inv * wg * &self.sigma_inv;
        let pbp = self.own_inv.iter().zip(&b.own).map(|(p, bb)| p * bb * p).collect();
        let a = self.own_inv.iter().zip(&g_own).map(|(p, gb)| p * gb * &self.sigma_inv).collect();
        let low = low.iter().map(|(c, x, y)| (*c, self.apply(x), self.apply(y))).collect();
        debug_assert_eq!(m.nrows(), ps);
        Sandwich { inv: self.clone(), pbp, a, m, low }
    }
}

impl Sandwich {
    /// Row g of `P G Σ⁻¹` (length p_s; 0 for a shared g).
    fn a_row(&self, g: usize) -> DVector<f64> {
        let l = &self.inv.layout;
        match l.owner[g] {
            None => DVector::zeros(l.shared.len()),
            Some(b) => self.a[b].row(l.pos[g]).transpose(),
        }
    }

    /// Entry (g, h); NaN in the row and column of an unseen column (as the dense sandwich
    /// with an infinite diagonal gives).
    ///
    /// # Panics
    /// If g or h is ≥ n.
    pub fn entry(&self, g: usize, h: usize) -> f64 {
        if self.inv.unseen[g] || self.inv.unseen[h] {
            return f64::NAN;
        }
        let l = &self.inv.layout;
        let pbp = match (l.owner[g], l.owner[h]) {
            (Some(a), Some(b)) if a == b => self.pbp[a][(l.pos[g], l.pos[h])],
            _ => 0.0,
        };
        let (wg, wh) = (self.inv.w_row(g), self.inv.w_row(h));
        let low: f64 = self.low.iter().map(|(c, u, v)| c * u[g] * v[h]).sum();
        pbp + self.a_row(g).dot(&wh) + wg.dot(&self.a_row(h)) + wg.dot(&(&self.m * &wh)) + low
    }
}
