//! The Levenberg-Marquardt parameter of a trust region (MINPACK's `lmpar`; Moré, "The
//! Levenberg-Marquardt algorithm: implementation and theory", *Numerical Analysis*, LNM
//! 630, 1978, sections 5 and 7), on the normal equations: given the radius Δ, the damping
//! λ ≥ 0 whose step `δ(λ) = (JᵀWJ + λ D)⁻¹ JᵀWε` has `‖δ‖_D` within 10 % of Δ, or λ = 0
//! where the Gauss-Newton step lies inside 1.1 Δ.
//!
//! MINPACK works on the QR factors of J (as the `qrpar` module does where the problem
//! keeps J); here J is not kept (a dynamic fit's JᵀWJ is a sum over the record), so each
//! trial λ is a Cholesky solve of `JᵀWJ + λ D` and the derivative of
//! `φ(λ) = ‖δ(λ)‖_D − Δ` is `φ' = −wᵀ(JᵀWJ + λ D)⁻¹w / ‖δ‖_D`, `w = D δ` (`D` the squared
//! scaling of [`super::Monitor`]): the same iteration in exact arithmetic, with JᵀWJ's
//! condition number where MINPACK has J's. A singular JᵀWJ has no Gauss-Newton step here
//! (MINPACK takes the basic solution of the leading nonsingular columns of J's pivoted
//! factor): λ starts above 0 instead.

use super::Gram;
use nalgebra::DVector;

/// At most this many λ iterations per call (MINPACK's 10).
pub(super) const MAX_ITERATIONS: usize = 10;

/// The step of trust radius `delta` (> 0) at the normal equations `jtj δ = jtr` (n × n and
/// n; `jtr = JᵀWε`, the steepest-descent direction), damping diagonal `d` (length n, all
/// positive), starting the search from the last call's λ `par` (≥ 0). Returns `(δ, λ)`; `None`
/// where no damped system can be solved (JᵀWJ not finite).
pub(super) fn lmpar(
    jtj: &Gram,
    jtr: &DVector<f64>,
    d: &DVector<f64>,
    delta: f64,
    par: f64,
) -> Option<(DVector<f64>, f64)> {
    let norm = |x: &DVector<f64>| x.iter().zip(d.iter()).map(|(x, d)| d * x * x).sum::<f64>().sqrt();
    // wᵀ(JᵀWJ + λD)⁻¹w / ‖δ‖²_D with w = Dδ: −φ'(λ) ‖δ‖_D / ‖δ‖²_D = MINPACK's `temp`.
    let curvature = |x: &DVector<f64>, dxnorm: f64, lambda: f64| {
        let w = DVector::from_fn(x.len(), |j, _| d[j] * x[j] / dxnorm);
        jtj.damped_solve(d, lambda, &w).map(|v| v.dot(&w)).filter(|t| t.is_finite() && *t > 0.0)
    };
    let gauss_newton = jtj.solve(jtr).filter(|x| x.iter().all(|v| v.is_finite()));
    let mut parl = 0.0;
    let mut fp = f64::INFINITY;
    let mut dxnorm_gn = f64::INFINITY;
    if let Some(x) = &gauss_newton {
        dxnorm_gn = norm(x);
        fp = dxnorm_gn - delta;
        if fp <= 0.1 * delta {
            return Some((x.clone(), 0.0));
        }
        // Lower bound: the Newton step on φ from λ = 0 (φ is convex and decreasing).
        if let Some(t) = curvature(x, dxnorm_gn, 0.0) {
            parl = (fp / delta) / t;
        }
    }
    // Upper bound: ‖D^{-1/2} JᵀWε‖ / Δ.
    let gnorm = jtr.iter().zip(d.iter()).map(|(g, d)| g * g / d).sum::<f64>().sqrt();
    let mut paru = upper_bound(gnorm, delta);
    let mut par = par.max(parl).min(paru);
    if par == 0.0 && dxnorm_gn.is_finite() {
        par = gnorm / dxnorm_gn;
    }
    let mut best = None;
    for iteration in 1..=MAX_ITERATIONS {
        if par == 0.0 {
            par = f64::MIN_POSITIVE.max(1e-3 * paru);
        }
        let Some(x) = jtj.damped_solve(d, par, jtr).filter(|x| x.iter().all(|v| v.is_finite())) else {
            // Not positive definite at this λ: more damping.
            parl = parl.max(par);
            par *= 10.0;
            continue;
        };
        let dxnorm = norm(&x);
        let previous = fp;
        fp = dxnorm - delta;
        let done = met(fp, previous, parl, delta, iteration);
        let Some(t) = (!done).then(|| curvature(&x, dxnorm, par)).flatten() else {
            return Some((x, par));
        };
        best = Some((x, par));
        par = next_par(par, (fp / delta) / t, fp, &mut parl, &mut paru);
    }
    best
}

/// MINPACK's upper bound on λ, `‖D^{-1/2} JᵀWε‖ / Δ` from `gnorm` and the radius `delta`,
/// or the smallest positive number over `min(Δ, 0.1)` where that is 0.
pub(super) fn upper_bound(gnorm: f64, delta: f64) -> f64 {
    let paru = gnorm / delta;
    if paru == 0.0 { f64::MIN_POSITIVE / delta.min(0.1) } else { paru }
}

/// MINPACK's end of the λ iteration after `iteration` steps (1-based): `φ = fp` within
/// 10 % of the radius `delta`, φ negative and falling from `previous` with no lower bound
/// (`parl = 0`: the step is inside the region and λ = 0 is near), or the last iteration.
pub(super) fn met(fp: f64, previous: f64, parl: f64, delta: f64, iteration: usize) -> bool {
    fp.abs() <= 0.1 * delta
        || (parl == 0.0 && fp <= previous && previous < 0.0)
        || iteration == MAX_ITERATIONS
}

/// MINPACK's λ update: the bracket `[parl, paru]` narrowed by the sign of `φ(λ) = fp`, and
/// the Newton correction `parc` taken from λ, kept at or above `parl`.
pub(super) fn next_par(par: f64, parc: f64, fp: f64, parl: &mut f64, paru: &mut f64) -> f64 {
    if fp > 0.0 {
        *parl = parl.max(par);
    } else if fp < 0.0 {
        *paru = paru.min(par);
    }
    parl.max(par + parc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    fn gram() -> Gram {
        Gram::Dense(DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 3.0]))
    }

    #[test]
    fn the_gauss_newton_step_inside_the_region_is_taken_undamped() {
        let (g, d) = (DVector::from_vec(vec![1.0, 2.0]), DVector::from_vec(vec![4.0, 3.0]));
        let (x, par) = lmpar(&gram(), &g, &d, 100.0, 0.5).expect("solvable");
        assert_eq!(par, 0.0);
        let gn = gram().solve(&g).expect("positive definite");
        assert_eq!(x, gn);
    }

    #[test]
    fn a_step_outside_the_region_is_damped_to_its_radius() {
        let (g, d) = (DVector::from_vec(vec![10.0, -20.0]), DVector::from_vec(vec![4.0, 3.0]));
        let delta = 0.5;
        let (x, par) = lmpar(&gram(), &g, &d, delta, 0.0).expect("solvable");
        let norm = (4.0 * x[0] * x[0] + 3.0 * x[1] * x[1]).sqrt();
        assert!(par > 0.0);
        assert!((norm - delta).abs() <= 0.1 * delta, "‖δ‖_D = {norm}");
        // δ solves the damped normal equations at the λ returned.
        let back = gram().damped_solve(&d, par, &g).expect("positive definite");
        assert!((back - &x).amax() <= 1e-12 * x.amax());
    }
}
