//! The square root of a problem's normal equations, [`Root`]: J's column-pivoted QR
//! factors as MINPACK's `qrfac` computes them (Moré, Garbow & Hillstrom, *User guide for
//! MINPACK-1*, ANL-80-74, 1980), with MINPACK's `enorm`, for the trust region's steps on
//! them (the `qrpar` module).

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// The square root of the normal equations at a point: `√W J P = Q R` (thin QR with the
/// columns permuted by P; `J = ∂ŷ/∂p` in the solver's scaled coordinates, m × n), so
/// `JᵀWJ = P RᵀR Pᵀ` and `JᵀWε = P Rᵀ qtf`. A problem gives it through
/// [`LeastSquares::root`](super::LeastSquares::root), built by [`Root::from_jacobian`]
/// (MINPACK's column pivoting) or [`Root::new`] (a factor of its own, unpivoted).
#[derive(Clone, Debug, PartialEq)]
pub struct Root {
    /// `R`, n × n upper triangular (rows beyond m zero where m < n).
    pub r: DMatrix<f64>,
    /// P as MINPACK's `ipvt`: column j of `J P` is column `ipvt[j]` of J (length n).
    pub ipvt: Vec<usize>,
    /// `Qᵀ √W ε`, length n.
    pub qtf: DVector<f64>,
    /// Whether P is MINPACK's pivoting by the columns' remaining norms ([`Root::from_jacobian`]):
    /// the factor then serves a step with every parameter free as it is.
    by_norm: bool,
}

impl Root {
    /// The root of the weighted Jacobian `j = √W J` (m × n) and weighted residuals
    /// `e = √W ε` (length m) by MINPACK's `qrfac` with column pivoting (Householder
    /// reflections, each column in turn the one of largest remaining norm; Businger & Golub
    /// 1965; Moré, Garbow & Hillstrom, *User guide for MINPACK-1*, ANL-80-74, 1980) and
    /// `Qᵀe` formed as `lmder` forms it, in MINPACK's order of operations: on a J whose
    /// condition number nears 1/ε_mach (Brown's almost-linear function from 100 x₀) the
    /// steps then follow MINPACK's. A J with fewer rows than columns is padded with zero
    /// rows. Non-finite entries give a non-finite root, with which the solver takes that
    /// point's step on the normal equations.
    ///
    /// # Errors
    /// [`Error::Solver`] when `e`'s length is not j's number of rows.
    pub fn from_jacobian(j: DMatrix<f64>, e: &DVector<f64>) -> Result<Self> {
        let (m, n) = j.shape();
        if e.len() != m {
            return Err(Error::Solver(format!("a root of a {m} × {n} Jacobian with {} residuals", e.len())));
        }
        let (j, b) = match m < n {
            true => (j.resize_vertically(n, 0.0), e.clone().resize_vertically(n, 0.0)),
            false => (j, e.clone()),
        };
        let f = qrfac(j, b);
        Ok(Self { r: f.r, ipvt: f.ipvt, qtf: f.qtb, by_norm: true })
    }

    /// A root of the caller's own: `R` n × n upper triangular and `qtf` with `√W J = Q R`
    /// (no column permutation); the solver pivots it again (MINPACK's `qrfac` on R).
    pub fn new(r: DMatrix<f64>, qtf: DVector<f64>) -> Self {
        let ipvt = (0..r.ncols()).collect();
        Self { r, ipvt, qtf, by_norm: false }
    }

    /// Checks the shapes against the n parameters of the problem: R n × n, `ipvt` a
    /// permutation of 0..n, `qtf` of length n.
    ///
    /// # Errors
    /// [`Error::Solver`] naming the shapes found.
    pub fn check(&self, n: usize) -> Result<()> {
        let mut seen = vec![false; n];
        let permutation = self.ipvt.len() == n
            && self.ipvt.iter().all(|&l| l < n && !std::mem::replace(&mut seen[l], true));
        if self.r.shape() != (n, n) || self.qtf.len() != n || !permutation {
            let (rows, cols) = self.r.shape();
            let len = self.qtf.len();
            return Err(Error::Solver(format!(
                "a root with R {rows} × {cols}, Qᵀε of length {len} and a column order {:?} for {n} parameters: \
                 LeastSquares::root must give R n × n, Qᵀε of length n and a permutation of 0..n",
                self.ipvt
            )));
        }
        Ok(())
    }

    /// Whether every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.r.iter().chain(self.qtf.iter()).all(|v| v.is_finite())
    }

    /// `R Pᵀ` (n × n), the factor in the parameters' own order: its Gram matrix is `JᵀWJ`.
    pub fn unpivoted(&self) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(self.r.nrows(), self.r.ncols());
        for (j, &l) in self.ipvt.iter().enumerate() {
            a.set_column(l, &self.r.column(j));
        }
        a
    }

    /// `R Pᵀ x` in MINPACK's order of operations (`lmder`'s `wa3`): `‖R Pᵀ x‖ = ‖√W J x‖`.
    pub(super) fn times(&self, x: &DVector<f64>) -> DVector<f64> {
        let mut y = DVector::zeros(self.r.nrows());
        for (j, &l) in self.ipvt.iter().enumerate() {
            let t = x[l];
            for i in 0..=j {
                y[i] += self.r[(i, j)] * t;
            }
        }
        y
    }

    /// MINPACK's `gnorm` (`lmder`), the largest cosine between `√W ε` and a column of
    /// `√W J`, from the factors: `max_j |(Rᵀ qtf)_j / ‖ε‖| / ‖R e_j‖` over the columns
    /// that are not zero, `rnorm = ‖√W ε‖`; 0 where `rnorm` is. The [`Tolerances`]'
    /// `gtol` test on it is MINPACK's, which ends a run at a gradient that is exactly 0
    /// with `gtol = 0`.
    ///
    /// [`Tolerances`]: super::Tolerances
    pub(super) fn gnorm(&self, rnorm: f64) -> f64 {
        if rnorm == 0.0 {
            return 0.0;
        }
        (0..self.ipvt.len())
            .filter_map(|j| {
                let norm = enorm(self.r.view((0, j), (j + 1, 1)).iter().copied());
                let mut sum = 0.0;
                for i in 0..=j {
                    sum += self.r[(i, j)] * (self.qtf[i] / rnorm);
                }
                (norm != 0.0).then(|| (sum / norm).abs())
            })
            .fold(0.0, f64::max)
    }

    /// The factor of the reduced problem of the columns `free` (the parameters not held at
    /// a bound): this root itself where every column is free and it is MINPACK's pivoting,
    /// else `R Pᵀ`'s columns `free` factored again with column pivoting.
    pub(super) fn pivoted(&self, free: &[usize]) -> Pivoted {
        if self.by_norm && free.len() == self.ipvt.len() && free.iter().enumerate().all(|(j, &c)| j == c) {
            return Pivoted { r: self.r.clone(), ipvt: self.ipvt.clone(), qtb: self.qtf.clone() };
        }
        qrfac(self.unpivoted().select_columns(free), self.qtf.clone())
    }
}

/// A column-pivoted triangular factor (MINPACK's `qrfac` with `pivot = true`): `A P = Q R`
/// with `|R_00| ≥ |R_11| ≥ …`, and `Qᵀb` of the right-hand side.
pub(super) struct Pivoted {
    /// `R`, k × k upper triangular.
    pub(super) r: DMatrix<f64>,
    /// Column j of `A P` is column `ipvt[j]` of A.
    pub(super) ipvt: Vec<usize>,
    /// `Qᵀb`, length k.
    pub(super) qtb: DVector<f64>,
}

/// MINPACK's `enorm`: the Euclidean norm of `x` with the small (≤ 3.834e-20), intermediate
/// and large (≥ 1.304e19 / len) components summed apart, scaled, so that no square under-
/// or overflows; the intermediate components alone give `√Σx²` summed in order.
pub(super) fn enorm(x: impl ExactSizeIterator<Item = f64>) -> f64 {
    const RDWARF: f64 = 3.834e-20;
    const RGIANT: f64 = 1.304e19;
    let agiant = RGIANT / x.len().max(1) as f64;
    let (mut s1, mut s2, mut s3, mut x1max, mut x3max) = (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    for v in x {
        let a = v.abs();
        if a > RDWARF && a < agiant {
            s2 += a * a;
        } else if a <= RDWARF {
            if a > x3max {
                let q = x3max / a;
                s3 = 1.0 + s3 * (q * q);
                x3max = a;
            } else if a != 0.0 {
                let q = a / x3max;
                s3 += q * q;
            }
        } else if a > x1max {
            let q = x1max / a;
            s1 = 1.0 + s1 * (q * q);
            x1max = a;
        } else {
            let q = a / x1max;
            s1 += q * q;
        }
    }
    if s1 != 0.0 {
        x1max * (s1 + (s2 / x1max) / x1max).sqrt()
    } else if s2 == 0.0 {
        x3max * s3.sqrt()
    } else if s2 >= x3max {
        (s2 * (1.0 + (x3max / s2) * (x3max * s3))).sqrt()
    } else {
        (x3max * ((s2 / x3max) + (x3max * s3))).sqrt()
    }
}

/// MINPACK's `qrfac` with `pivot = true` on `a` (n × k, n ≥ k) in its order of operations
/// (each Householder vector scaled to a unit leading entry plus one; the remaining columns'
/// norms downdated, computed again where cancellation has eaten them), followed by `lmder`'s
/// product `Qᵀb` (b of length n) with the stored vectors.
fn qrfac(mut a: DMatrix<f64>, mut b: DVector<f64>) -> Pivoted {
    let (n, k) = a.shape();
    let mut ipvt: Vec<usize> = (0..k).collect();
    let mut rdiag: Vec<f64> = (0..k).map(|c| enorm(a.column(c).iter().copied())).collect();
    let mut wa = rdiag.clone();
    for j in 0..k.min(n) {
        let kmax = (j..k).fold(j, |best, c| if rdiag[c] > rdiag[best] { c } else { best });
        if kmax != j {
            a.swap_columns(j, kmax);
            rdiag[kmax] = rdiag[j];
            wa[kmax] = wa[j];
            ipvt.swap(j, kmax);
        }
        let mut ajnorm = enorm(a.view((j, j), (n - j, 1)).iter().copied());
        if ajnorm != 0.0 {
            if a[(j, j)] < 0.0 {
                ajnorm = -ajnorm;
            }
            for i in j..n {
                a[(i, j)] /= ajnorm;
            }
            a[(j, j)] += 1.0;
            for c in j + 1..k {
                let mut sum = 0.0;
                for i in j..n {
                    sum += a[(i, j)] * a[(i, c)];
                }
                let t = sum / a[(j, j)];
                for i in j..n {
                    a[(i, c)] -= t * a[(i, j)];
                }
                if rdiag[c] != 0.0 {
                    let t = a[(j, c)] / rdiag[c];
                    rdiag[c] *= (1.0 - t * t).max(0.0).sqrt();
                    let q = rdiag[c] / wa[c];
                    if 0.05 * (q * q) <= f64::EPSILON {
                        rdiag[c] = enorm(a.view((j + 1, c), (n - j - 1, 1)).iter().copied());
                        wa[c] = rdiag[c];
                    }
                }
            }
        }
        rdiag[j] = -ajnorm;
    }
    // Qᵀb with the Householder vectors below the diagonal (lmder's qtf), then R.
    for j in 0..k.min(n) {
        if a[(j, j)] != 0.0 {
            let mut sum = 0.0;
            for i in j..n {
                sum += a[(i, j)] * b[i];
            }
            let t = -sum / a[(j, j)];
            for i in j..n {
                b[i] += a[(i, j)] * t;
            }
        }
        a[(j, j)] = rdiag[j];
    }
    let r = a.rows(0, k).upper_triangle();
    Pivoted { r, ipvt, qtb: b.rows(0, k).into_owned() }
}
