//! Steps with parameters held at the bounds they are pressed against (an active set), for
//! the damped solvers (Gauss-Newton, both Levenberg-Marquardts): the components at a bound that the steepest-descent direction, or a step
//! solved for the others, would push out of the box are held there, and the normal
//! equations are solved again for the rest, until no free component points out (at most
//! n + 1 solves). Every parameter at a bound then moves inwards or not at all, so the step
//! needs no projection in those components and the others are the bounded problem's step,
//! not the unbounded one's cut off at the bound (Bertsekas, *SIAM J. Control Optim.* 20(2),
//! 1982, the projected Newton method; Kelley, *Iterative Methods for Optimization*, 1999,
//! section 5.5). Without a parameter at a bound this is the plain step, to the bit.

use super::{Gram, LeastSquares};
use argmin::core::Problem;
use nalgebra::DVector;

/// A step `δ` (scaled space, length n) with its parameters at bounds held: zero in the
/// held components.
pub(super) struct HeldStep {
    /// δ, zero in the held components.
    pub delta: DVector<f64>,
    /// The largest of the solves' auxiliary numbers (the Gauss-Newton solve's shift μ).
    pub aux: f64,
    /// Number of parameters held at a bound.
    pub held: usize,
}

/// The components of `p` (length n) at a bound that a move along `d` would push out of
/// the box: a short probe along `sign(d)` is projected straight back onto `p`.
///
/// # Errors
/// Those of the problem's projection.
fn outward<O: LeastSquares>(
    problem: &mut Problem<O>,
    p: &DVector<f64>,
    d: &DVector<f64>,
) -> Result<Vec<bool>, argmin::core::Error> {
    let n = p.len();
    let mut q = DVector::from_fn(n, |j, _| p[j] + d[j].signum() * 1e-6 * (p[j].abs() + 1.0));
    problem.problem("project_count", |o| {
        o.project(&mut q);
        Ok(())
    })?;
    Ok((0..n).map(|j| d[j] != 0.0 && q[j] == p[j]).collect())
}

/// `solve(H, g)` on the normal equations `H δ = g` (`jtj`, `jtr`, n × n and n) reduced to
/// the components not `held`: a dense `H` by selecting the free rows and columns (and `g`'s
/// and the damping diagonal `d`'s free entries), an arrowhead by identity rows with a zero
/// right-hand side at the held ones. `solve` receives the reduced `H`, `g` and `d` and the
/// free components' indices (ascending; for an arrowhead the system stays n × n), and
/// returns δ and an auxiliary number; `None` where it fails.
fn reduced(
    jtj: &Gram,
    jtr: &DVector<f64>,
    d: &DVector<f64>,
    held: &[bool],
    solve: &mut impl FnMut(&Gram, &DVector<f64>, &DVector<f64>, &[usize]) -> Option<(DVector<f64>, f64)>,
) -> Option<(DVector<f64>, f64)> {
    let n = jtr.len();
    let free: Vec<usize> = (0..n).filter(|&j| !held[j]).collect();
    if free.len() == n {
        return solve(jtj, jtr, d, &free);
    }
    let mut delta = DVector::zeros(n);
    if free.is_empty() {
        return Some((delta, 0.0));
    }
    let (found, aux) = match jtj {
        Gram::Dense(m) => {
            let h = Gram::Dense(m.select_rows(&free).select_columns(&free));
            let (found, aux) = solve(&h, &jtr.select_rows(&free), &d.select_rows(&free), &free)?;
            let mut full = DVector::zeros(n);
            for (k, &j) in free.iter().enumerate() {
                full[j] = found[k];
            }
            (full, aux)
        }
        Gram::Arrow(a) => {
            let h = Gram::from(a.with_identity_at(held));
            let g = DVector::from_fn(n, |j, _| if held[j] { 0.0 } else { jtr[j] });
            solve(&h, &g, d, &free)?
        }
    };
    for &j in &free {
        delta[j] = found[j];
    }
    Some((delta, aux))
}

/// The step at `p` (length n) from the normal equations `jtj δ = jtr` (`jtr = JᵀWε`, the
/// steepest-descent direction) by `solve` (module docs), with the parameters pressed
/// against a bound held: first those where `jtr` points out of the box, then any whose
/// reduced step points out. `d` is the damping diagonal passed on to `solve`. `None` where
/// `solve` fails.
///
/// # Errors
/// Those of the problem's projection.
pub(super) fn held_step<O: LeastSquares>(
    problem: &mut Problem<O>,
    p: &DVector<f64>,
    jtj: &Gram,
    jtr: &DVector<f64>,
    d: &DVector<f64>,
    mut solve: impl FnMut(&Gram, &DVector<f64>, &DVector<f64>, &[usize]) -> Option<(DVector<f64>, f64)>,
) -> Result<Option<HeldStep>, argmin::core::Error> {
    let mut held = outward(problem, p, jtr)?;
    let mut aux: f64 = 0.0;
    loop {
        let Some((delta, a)) = reduced(jtj, jtr, d, &held, &mut solve) else { return Ok(None) };
        aux = aux.max(a);
        let blocked = outward(problem, p, &delta)?;
        let mut grew = false;
        for (h, b) in held.iter_mut().zip(blocked) {
            if b && !*h {
                *h = true;
                grew = true;
            }
        }
        if !grew {
            return Ok(Some(HeldStep { delta, aux, held: held.iter().filter(|&&h| h).count() }));
        }
    }
}
