//! The matrix `JᵀWJ` as the solvers see it ([`Gram`]): dense, or of block-arrowhead
//! structure (a joint fit of many experiments with per-experiment parameters).

use crate::estimate::arrowhead::Arrowhead;
use nalgebra::{DMatrix, DVector};

/// `JᵀWJ` (n_free × n_free, symmetric): dense, or stored by the blocks of its arrowhead
/// structure ([`Arrowhead`]), solved by the Schur complement.
#[derive(Clone, Debug, PartialEq)]
pub enum Gram {
    /// Every entry.
    Dense(DMatrix<f64>),
    /// The blocks of an arrowhead matrix.
    Arrow(Box<Arrowhead>),
}

impl From<DMatrix<f64>> for Gram {
    fn from(m: DMatrix<f64>) -> Self {
        Self::Dense(m)
    }
}

impl From<Arrowhead> for Gram {
    fn from(m: Arrowhead) -> Self {
        Self::Arrow(Box::new(m))
    }
}

static ZERO: f64 = 0.0;

impl std::ops::Index<(usize, usize)> for Gram {
    type Output = f64;
    /// Entry (r, c) (0 outside an arrowhead's structure).
    fn index(&self, (r, c): (usize, usize)) -> &f64 {
        match self {
            Self::Dense(m) => &m[(r, c)],
            Self::Arrow(a) => a.get_ref(r, c).unwrap_or(&ZERO),
        }
    }
}

impl Gram {
    /// Number of rows (and columns) n.
    pub fn nrows(&self) -> usize {
        match self {
            Self::Dense(m) => m.nrows(),
            Self::Arrow(a) => a.n(),
        }
    }
    /// The diagonal (length n).
    pub fn diagonal(&self) -> DVector<f64> {
        match self {
            Self::Dense(m) => m.diagonal(),
            Self::Arrow(a) => a.diagonal(),
        }
    }
    /// `A x` (x of length n).
    pub fn mul(&self, x: &DVector<f64>) -> DVector<f64> {
        match self {
            Self::Dense(m) => m * x,
            Self::Arrow(a) => a.mul(x),
        }
    }
    /// The dense matrix, when it is stored so.
    pub fn as_dense(&self) -> Option<&DMatrix<f64>> {
        match self {
            Self::Dense(m) => Some(m),
            Self::Arrow(_) => None,
        }
    }
    /// Every entry as a dense matrix (a copy for an arrowhead: n² numbers).
    pub fn to_dense(&self) -> DMatrix<f64> {
        match self {
            Self::Dense(m) => m.clone(),
            Self::Arrow(a) => a.to_dense(),
        }
    }
    /// Whether every entry is finite.
    pub fn is_finite(&self) -> bool {
        match self {
            Self::Dense(m) => m.iter().all(|v| v.is_finite()),
            Self::Arrow(a) => a.is_finite(),
        }
    }

    /// Solves `(A + λ diag(d)) δ = g` by Cholesky (an arrowhead by its Schur complement);
    /// `None` when the matrix is not positive definite.
    pub fn damped_solve(&self, d: &DVector<f64>, lambda: f64, g: &DVector<f64>) -> Option<DVector<f64>> {
        match self {
            Self::Dense(h) => {
                let mut a = h.clone();
                for j in 0..a.nrows() {
                    a[(j, j)] += lambda * d[j];
                }
                a.cholesky().map(|c| c.solve(g))
            }
            Self::Arrow(a) => a.damped_solve(d, lambda, g).ok(),
        }
    }

    /// Solves `A δ = g` by Cholesky; `None` when A is not positive definite.
    pub fn solve(&self, g: &DVector<f64>) -> Option<DVector<f64>> {
        match self {
            Self::Dense(h) => h.clone().cholesky().map(|c| c.solve(g)),
            Self::Arrow(a) => a.damped_solve(&DVector::zeros(a.n()), 0.0, g).ok(),
        }
    }
}
