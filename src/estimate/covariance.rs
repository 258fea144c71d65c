//! The inverses and sandwich covariances of a fit's statistics, dense or by arrowhead
//! blocks: entries on request, so that a joint fit of many experiments never forms an
//! n_free × n_free matrix (MODEL.md §5; the block formulas in [`super::arrowhead`]).

use super::arrowhead::{ArrowInverse, LowRank, Sandwich};
use super::problem::BatchMeans;
use super::solver::Gram;
use nalgebra::{DMatrix, DVector};

/// The inverse of a symmetric positive semi-definite [`Gram`] on its support (columns with
/// a positive diagonal; the others ∞ on the diagonal, 0 elsewhere).
pub(crate) enum Inverse {
    Dense(DMatrix<f64>),
    Arrow(ArrowInverse),
}

impl Inverse {
    /// `Err` when the supported part is not positive definite: for an arrowhead, with the
    /// column where its elimination failed (its block's, or the first shared one).
    pub(crate) fn of(a: &Gram) -> Result<Self, Option<usize>> {
        match a {
            Gram::Dense(m) => inverse_on_support(m).map(Self::Dense).ok_or(None),
            Gram::Arrow(m) => m.inverse_on_support().map(Self::Arrow).map_err(|s| Some(s.column)),
        }
    }

    /// Entry (g, h).
    pub(crate) fn entry(&self, g: usize, h: usize) -> f64 {
        match self {
            Self::Dense(m) => m[(g, h)],
            Self::Arrow(a) => a.entry(g, h),
        }
    }

    /// `A⁻¹ x` with the non-finite entries of `A⁻¹` (unseen columns) taken as 0.
    pub(crate) fn apply_finite(&self, x: &DVector<f64>) -> DVector<f64> {
        match self {
            Self::Dense(ai) => {
                let finite = DMatrix::from_fn(ai.nrows(), ai.ncols(), |i, j| {
                    if ai[(i, j)].is_finite() { ai[(i, j)] } else { 0.0 }
                });
                finite * x
            }
            Self::Arrow(a) => a.apply(x),
        }
    }
}

/// A θ-space covariance `dθ_g dθ_h (A⁻¹ B A⁻¹)_gh` of the free entries.
pub(crate) enum Covariance {
    Dense(DMatrix<f64>),
    Arrow(Box<Sandwich>, Vec<f64>),
}

impl Covariance {
    /// The sandwich of `bread_inv` around `meat` (dense), or around a batch-means meat
    /// kept by blocks, chained by `dtheta`; `None` when there is no inverse or the meat's
    /// storage does not match it.
    pub(crate) fn sandwich(bread_inv: &Option<Inverse>, meat: Meat<'_>, dtheta: &[f64]) -> Option<Self> {
        match (bread_inv.as_ref()?, meat) {
            (Inverse::Dense(ai), Meat::Gram(Gram::Dense(meat))) => Some(dense_sandwich(ai, meat, dtheta)),
            (Inverse::Dense(ai), Meat::Batches(b)) if b.arrow.is_none() => {
                Some(dense_sandwich(ai, &b.meat, dtheta))
            }
            (Inverse::Arrow(ai), Meat::Gram(Gram::Arrow(meat))) => {
                Some(Self::Arrow(Box::new(ai.sandwich(meat, &LowRank::new())), dtheta.to_vec()))
            }
            (Inverse::Arrow(ai), Meat::Batches(BatchMeans { arrow: Some((meat, low)), .. })) => {
                Some(Self::Arrow(Box::new(ai.sandwich(meat, low)), dtheta.to_vec()))
            }
            _ => None,
        }
    }

    /// Entry (g, h) in θ units.
    pub(crate) fn entry(&self, g: usize, h: usize) -> f64 {
        match self {
            Self::Dense(c) => c[(g, h)],
            Self::Arrow(s, d) => s.entry(g, h) * d[g] * d[h],
        }
    }
}

/// `dθ_i dθ_j (A⁻¹ B A⁻¹)_ij`.
fn dense_sandwich(ai: &DMatrix<f64>, meat: &DMatrix<f64>, dtheta: &[f64]) -> Covariance {
    let np = dtheta.len();
    let cov_p = ai * meat * ai;
    Covariance::Dense(DMatrix::from_fn(np, np, |i, j| cov_p[(i, j)] * dtheta[i] * dtheta[j]))
}

/// The meat of a sandwich: the white one (a [`Gram`]) or the batch means'.
#[derive(Clone, Copy)]
pub(crate) enum Meat<'a> {
    Gram(&'a Gram),
    Batches(&'a BatchMeans),
}

/// Inverse of a symmetric positive semi-definite matrix on the rows/columns with a
/// non-zero diagonal (Cholesky); the others get ∞ on the diagonal and 0 elsewhere. `None`
/// when the supported block is not positive definite.
fn inverse_on_support(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = a.nrows();
    let live: Vec<usize> = (0..n).filter(|&i| a[(i, i)] > 0.0).collect();
    let sub = DMatrix::from_fn(live.len(), live.len(), |i, j| a[(live[i], live[j])]);
    let inv = sub.cholesky()?.inverse();
    let mut out = DMatrix::zeros(n, n);
    for i in 0..n {
        if a[(i, i)] <= 0.0 {
            out[(i, i)] = f64::INFINITY;
        }
    }
    for (i, &r) in live.iter().enumerate() {
        for (j, &c) in live.iter().enumerate() {
            out[(r, c)] = inv[(i, j)];
        }
    }
    Some(out)
}
