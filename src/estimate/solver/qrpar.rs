//! The trust-region step on J's QR factors, as MINPACK takes it (`qrfac`, `lmpar`,
//! `qrsolv`; Moré, "The Levenberg-Marquardt algorithm: implementation and theory",
//! *Numerical Analysis*, LNM 630, 1978, sections 3, 5 and 7; Moré, Garbow & Hillstrom,
//! *User guide for MINPACK-1*, ANL-80-74, 1980): where a problem gives the square root of
//! its normal equations ([`Root`](super::Root)), the damped systems are solved as least-squares problems
//! `[J; √λ D^{1/2}] δ ≈ [ε; 0]` by Givens rotations of the triangular factor, with J's
//! condition number instead of JᵀWJ's (its square), and a rank-deficient J gets MINPACK's
//! Gauss-Newton step of the leading nonsingular columns (column pivoting by norm) instead of
//! none. The iteration on λ is the normal-equation `lmpar`'s (the `lmpar` module).

use super::lmpar::{MAX_ITERATIONS, met, next_par, upper_bound};
use super::root::{Pivoted, enorm};
use nalgebra::{DMatrix, DVector};

/// MINPACK's `qrsolv`: with `s` the diagonal scaling (length k, `√λ D^{1/2}` in the
/// pivoted problem's original column order), solves `[R Pᵀ; S] x ≈ [qtb; 0]` in the least-
/// squares sense by Givens rotations. Returns x (original order) and the work matrix whose
/// strict lower triangle holds the transposed new factor, with its diagonal `sdiag`.
fn qrsolv(f: &Pivoted, s: &DVector<f64>) -> (DVector<f64>, DMatrix<f64>, DVector<f64>) {
    let k = f.r.nrows();
    let mut r = f.r.clone();
    let mut wa = f.qtb.clone();
    let mut sdiag = DVector::zeros(k);
    for j in 0..k {
        for i in j + 1..k {
            r[(i, j)] = r[(j, i)];
        }
    }
    for j in 0..k {
        let l = f.ipvt[j];
        if s[l] != 0.0 {
            sdiag.rows_mut(j, k - j).fill(0.0);
            sdiag[j] = s[l];
            let mut qtbpj = 0.0;
            for c in j..k {
                if sdiag[c] == 0.0 {
                    continue;
                }
                let (sin, cos) = if r[(c, c)].abs() < sdiag[c].abs() {
                    let cotan = r[(c, c)] / sdiag[c];
                    let sin = 0.5 / (0.25 + 0.25 * cotan * cotan).sqrt();
                    (sin, sin * cotan)
                } else {
                    let tan = sdiag[c] / r[(c, c)];
                    let cos = 0.5 / (0.25 + 0.25 * tan * tan).sqrt();
                    (cos * tan, cos)
                };
                r[(c, c)] = cos * r[(c, c)] + sin * sdiag[c];
                let t = cos * wa[c] + sin * qtbpj;
                qtbpj = -sin * wa[c] + cos * qtbpj;
                wa[c] = t;
                for i in c + 1..k {
                    let t = cos * r[(i, c)] + sin * sdiag[i];
                    sdiag[i] = -sin * r[(i, c)] + cos * sdiag[i];
                    r[(i, c)] = t;
                }
            }
        }
        sdiag[j] = r[(j, j)];
        r[(j, j)] = f.r[(j, j)];
    }
    // The new factor is stored transposed in r's strict lower triangle.
    let x = triangular(&sdiag, wa, |j, i| r[(i, j)]);
    (unpivot(&f.ipvt, &x), r, sdiag)
}

/// Back substitution on `T z = w` for an upper triangular T of diagonal `diag` whose entry
/// in row j, column i > j is `above(j, i)`; the components from the first zero diagonal on
/// are set to 0 (MINPACK's `nsing`: the basic solution of the leading nonsingular columns).
fn triangular(diag: &DVector<f64>, mut w: DVector<f64>, above: impl Fn(usize, usize) -> f64) -> DVector<f64> {
    let k = diag.len();
    let nsing = (0..k).find(|&j| diag[j] == 0.0).unwrap_or(k);
    w.rows_mut(nsing, k - nsing).fill(0.0);
    for j in (0..nsing).rev() {
        let sum: f64 = (j + 1..nsing).map(|i| above(j, i) * w[i]).sum();
        w[j] = (w[j] - sum) / diag[j];
    }
    w
}

/// x in the original column order from z in the pivoted one.
fn unpivot(ipvt: &[usize], z: &DVector<f64>) -> DVector<f64> {
    let mut x = DVector::zeros(z.len());
    for (j, &l) in ipvt.iter().enumerate() {
        x[l] = z[j];
    }
    x
}

/// `‖diag · x‖` ([`enorm`]).
fn scaled_norm(diag: &DVector<f64>, x: &DVector<f64>) -> f64 {
    enorm(x.iter().zip(diag.iter()).map(|(x, d)| d * x))
}

/// The Gauss-Newton step `R z = qtb` of `lmpar`, by columns (MINPACK's order), with the
/// components from `nsing` (R's first zero diagonal, or k) on set to 0.
fn gauss_newton(r: &DMatrix<f64>, mut z: DVector<f64>, nsing: usize) -> DVector<f64> {
    let k = z.len();
    z.rows_mut(nsing, k - nsing).fill(0.0);
    for j in (0..nsing).rev() {
        z[j] /= r[(j, j)];
        let t = z[j];
        for i in 0..j {
            z[i] -= r[(i, j)] * t;
        }
    }
    z
}

/// `Rᵀ w = z` by forward substitution on R's columns (MINPACK's `parl`).
fn transposed(r: &DMatrix<f64>, mut z: DVector<f64>) -> DVector<f64> {
    for j in 0..z.len() {
        let mut sum = 0.0;
        for i in 0..j {
            sum += r[(i, j)] * z[i];
        }
        z[j] = (z[j] - sum) / r[(j, j)];
    }
    z
}

/// `y = T⁻ᵀ z` by forward substitution on the lower-stored factor (MINPACK's correction
/// step): `z` in pivoted order, T's transpose in `r`'s strict lower triangle, diagonal `diag`.
fn forward(r: &DMatrix<f64>, diag: &DVector<f64>, mut z: DVector<f64>) -> DVector<f64> {
    let k = z.len();
    for j in 0..k {
        z[j] /= diag[j];
        let t = z[j];
        for i in j + 1..k {
            z[i] -= r[(i, j)] * t;
        }
    }
    z
}

/// MINPACK's `lmpar` on a pivoted factor: the step `x` (original column order, length k)
/// whose scaled length `‖diag · x‖` is within 10 % of the radius `delta` (> 0), or the
/// Gauss-Newton step where it lies inside 1.1 `delta`, and its λ, starting from `par`
/// (≥ 0). `diag` (length k, all > 0) is MINPACK's scaling, the square root of the normal-
/// equation solvers' `D`. A Gauss-Newton step that is not finite (R singular to working
/// precision) is passed over for λ > 0, as the normal-equation `lmpar` does; `None` where
/// no damped step is finite.
pub(super) fn lmpar_qr(
    f: &Pivoted,
    diag: &DVector<f64>,
    delta: f64,
    par: f64,
) -> Option<(DVector<f64>, f64)> {
    let k = f.r.ncols();
    let dwarf = f64::MIN_POSITIVE;
    let nsing = (0..k).find(|&j| f.r[(j, j)] == 0.0).unwrap_or(k);
    let gn = unpivot(&f.ipvt, &gauss_newton(&f.r, f.qtb.clone(), nsing));
    let mut dxnorm = scaled_norm(diag, &gn);
    let mut fp = dxnorm - delta;
    let finite = fp.is_finite();
    if finite && fp <= 0.1 * delta {
        return Some((gn, 0.0));
    }
    // The pivoted `diag² x / ‖diag x‖`, whose T⁻ᵀ-image gives φ'(λ).
    let scaled_direction = |x: &DVector<f64>, dxnorm: f64| {
        DVector::from_fn(k, |j, _| {
            let l = f.ipvt[j];
            diag[l] * (diag[l] * x[l] / dxnorm)
        })
    };
    if !finite {
        fp = f64::INFINITY;
    }
    // Lower bound: the Newton step on φ from λ = 0, where R is nonsingular (Rᵀw = the
    // scaled direction by forward substitution).
    let mut parl = 0.0;
    if nsing == k && finite {
        let w = transposed(&f.r, scaled_direction(&gn, dxnorm));
        let t = enorm(w.iter().copied());
        let bound = ((fp / delta) / t) / t;
        if bound.is_finite() {
            parl = bound;
        }
    }
    let g =
        DVector::from_fn(k, |j, _| (0..=j).map(|i| f.r[(i, j)] * f.qtb[i]).sum::<f64>() / diag[f.ipvt[j]]);
    let gnorm = enorm(g.iter().copied());
    let mut paru = upper_bound(gnorm, delta);
    let mut par = par.max(parl).min(paru);
    if par == 0.0 && finite {
        par = gnorm / dxnorm;
    }
    for iteration in 1..=MAX_ITERATIONS {
        if par == 0.0 {
            par = dwarf.max(1e-3 * paru);
        }
        let (x, r, sdiag) = qrsolv(f, &(diag * par.sqrt()));
        dxnorm = scaled_norm(diag, &x);
        let previous = fp;
        fp = dxnorm - delta;
        if !fp.is_finite() {
            return None;
        }
        if met(fp, previous, parl, delta, iteration) {
            return Some((x, par));
        }
        let t = enorm(forward(&r, &sdiag, scaled_direction(&x, dxnorm)).iter().copied());
        if !(t.is_finite() && t > 0.0) {
            return Some((x, par));
        }
        par = next_par(par, ((fp / delta) / t) / t, fp, &mut parl, &mut paru);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::super::root::Root;
    use super::*;

    fn jacobian() -> (DMatrix<f64>, DVector<f64>) {
        let j = DMatrix::from_row_slice(4, 3, &[1.0, 2.0, 0.5, 0.0, 1.0, 3.0, 2.0, -1.0, 1.0, 1.0, 1.0, 1.0]);
        (j, DVector::from_vec(vec![1.0, -2.0, 0.5, 3.0]))
    }

    #[test]
    fn the_root_squares_to_the_normal_equations() {
        let (j, e) = jacobian();
        let root = Root::from_jacobian(j.clone(), &e).expect("shapes agree");
        let u = root.unpivoted();
        assert!((u.tr_mul(&u) - j.tr_mul(&j)).amax() <= 1e-13);
        assert!((u.tr_mul(&root.qtf) - j.tr_mul(&e)).amax() <= 1e-13);
        // MINPACK's pivoting: R's diagonal falls in magnitude, and `times` is `√W J x`.
        assert!((0..2).all(|i| root.r[(i, i)].abs() >= root.r[(i + 1, i + 1)].abs()));
        let x = DVector::from_vec(vec![0.3, -1.0, 2.0]);
        assert!((root.times(&x).norm() - (&j * &x).norm()).abs() <= 1e-13);
        let piv = root.pivoted(&[0, 2]);
        let a = u.select_columns(&[0, 2]);
        let ap = a.select_columns(&piv.ipvt);
        assert!((piv.r.tr_mul(&piv.r) - ap.tr_mul(&ap)).amax() <= 1e-13);
        assert!(piv.r[(0, 0)].abs() >= piv.r[(1, 1)].abs());
    }

    #[test]
    fn the_damped_step_solves_the_damped_normal_equations() {
        let (j, e) = jacobian();
        let piv = Root::from_jacobian(j.clone(), &e).expect("shapes agree").pivoted(&[0, 1, 2]);
        let diag = DVector::from_vec(vec![2.0, 0.5, 1.5]);
        let gn = j.clone().svd(true, true).solve(&e, 0.0).expect("full rank");
        let (x, par) = lmpar_qr(&piv, &diag, 1e3, 0.0).expect("finite");
        assert_eq!(par, 0.0);
        assert!((&x - gn).amax() <= 1e-12);
        let delta = 0.1;
        let (x, par) = lmpar_qr(&piv, &diag, delta, 0.0).expect("finite");
        assert!(par > 0.0 && (scaled_norm(&diag, &x) - delta).abs() <= 0.1 * delta);
        let d2 = DMatrix::from_diagonal(&diag.component_mul(&diag));
        let back = (j.tr_mul(&j) + d2 * par).cholesky().expect("positive definite").solve(&j.tr_mul(&e));
        assert!((back - &x).amax() <= 1e-12 * x.amax());
    }

    #[test]
    fn a_rank_deficient_jacobian_gets_a_gauss_newton_step() {
        // A column of zeros: JᵀJ is singular, R's last pivot exactly 0.
        let j = DMatrix::from_row_slice(3, 3, &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0]);
        let e = DVector::from_vec(vec![1.0, 2.0, 4.0]);
        let piv = Root::from_jacobian(j.clone(), &e).expect("shapes agree").pivoted(&[0, 1, 2]);
        let (x, par) = lmpar_qr(&piv, &DVector::from_element(3, 1.0), 1e3, 0.0).expect("finite");
        assert_eq!(par, 0.0);
        assert_eq!(x[1], 0.0);
        // The least-squares solution: the residual is orthogonal to J's columns.
        assert!(j.tr_mul(&(&j * &x - &e)).amax() <= 1e-12, "{x}");
    }

    #[test]
    fn a_short_jacobian_is_padded_and_a_held_column_left_out() {
        // m = 2 < n = 3: R has a zero last row; JᵀJ is singular.
        let j = DMatrix::from_row_slice(2, 3, &[1.0, 2.0, 0.0, 0.5, -1.0, 3.0]);
        let e = DVector::from_vec(vec![1.0, 2.0]);
        let root = Root::from_jacobian(j.clone(), &e).expect("shapes agree");
        assert_eq!(root.r.shape(), (3, 3));
        let u = root.unpivoted();
        assert!((u.tr_mul(&u) - j.tr_mul(&j)).amax() <= 1e-13);
        assert!((u.tr_mul(&root.qtf) - j.tr_mul(&e)).amax() <= 1e-13);
        // Column 1 held: the step of the other two solves the reduced damped system.
        let free = [0, 2];
        let diag = DVector::from_vec(vec![1.5, 0.5]);
        let (x, par) = lmpar_qr(&root.pivoted(&free), &diag, 0.05, 0.0).expect("finite");
        let jr = j.select_columns(&free);
        let d2 = DMatrix::from_diagonal(&diag.component_mul(&diag));
        let back = (jr.tr_mul(&jr) + d2 * par).cholesky().expect("positive definite").solve(&jr.tr_mul(&e));
        assert!(par > 0.0 && (back - &x).amax() <= 1e-12 * x.amax(), "{x}");
    }

    #[test]
    fn enorm_is_the_norm_without_overflow_or_underflow() {
        let plain = [3.0, -4.0, 12.0];
        assert_eq!(enorm(plain.iter().copied()), 13.0);
        // Squares of these would overflow and underflow.
        assert!((enorm([3e200, 4e200].into_iter()) / 5e200 - 1.0).abs() <= 1e-15);
        assert!((enorm([3e-200, -4e-200].into_iter()) / 5e-200 - 1.0).abs() <= 1e-15);
        assert!((enorm([1e-30, 1.0, 1e30].into_iter()) / 1e30 - 1.0).abs() <= 1e-15);
        assert_eq!(enorm(std::iter::empty()), 0.0);
    }

    #[test]
    fn a_root_of_its_own_gives_the_pivoted_roots_steps() {
        // R of nalgebra's unpivoted QR, pivoted again by the solver: the same damped step.
        let (j, e) = jacobian();
        let qr = j.clone().qr();
        let mut b = e.clone();
        qr.q_tr_mul(&mut b);
        let own = Root::new(qr.r(), b.rows(0, 3).into_owned());
        assert!(own.check(3).is_ok());
        let minpack = Root::from_jacobian(j, &e).expect("shapes agree");
        let diag = DVector::from_vec(vec![2.0, 0.5, 1.5]);
        let (x, par) = lmpar_qr(&own.pivoted(&[0, 1, 2]), &diag, 0.1, 0.0).expect("finite");
        let (y, qar) = lmpar_qr(&minpack.pivoted(&[0, 1, 2]), &diag, 0.1, 0.0).expect("finite");
        assert!((par - qar).abs() <= 1e-12 * par && (x - y).amax() <= 1e-12, "λ {par} vs {qar}");
    }

    #[test]
    fn a_root_of_the_wrong_shape_is_an_error() {
        let (j, e) = jacobian();
        assert!(Root::from_jacobian(j.clone(), &e.rows(0, 3).into_owned()).is_err());
        let root = Root::from_jacobian(j, &e).expect("shapes agree");
        assert!(root.check(3).is_ok());
        let err = root.check(4).expect_err("3 × 3 for 4 parameters").to_string();
        assert!(err.contains("4 parameters"), "{err}");
        let mut twice = root;
        twice.ipvt = vec![0, 0, 2];
        assert!(twice.check(3).expect_err("not a permutation").to_string().contains("permutation"));
    }
}
