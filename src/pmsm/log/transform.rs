//! Clarke and Park transforms, and dq signals from logged phase quantities.
//!
//! Conventions (MODEL.md §1): amplitude-invariant Clarke
//! `x_αβ = (2/3)(x_a + x_b e^{j2π/3} + x_c e^{−j2π/3})`, so a phase peak `X̂` gives
//! `|x_αβ| = X̂`; Park `x_dq = x_αβ e^{−jθ_e}` with the **electrical** angle
//! `θ_e = n_p θ_m`, the d axis on the magnet flux. Complex vectors are passed as
//! `(real, imaginary)` pairs: `(α, β)` or `(d, q)`.
//!
//! Source: P. C. Krause, O. Wasynczuk, S. D. Sudhoff, *Analysis of Electric Machinery and
//! Drive Systems*, 3rd ed., Wiley 2013, ch. 3 (reference-frame theory; the amplitude-
//! invariant scaling is its `K_s` with factor 2/3 and the zero sequence dropped).

use crate::error::{Error, Result};

const SQRT3: f64 = 1.732_050_807_568_877_2;

/// Amplitude-invariant Clarke transform of phase values `(x_a, x_b, x_c)` → `(x_α, x_β)`,
/// same unit as the input (A or V, peak scaling).
///
/// `x_α + j x_β = (2/3)(x_a + x_b e^{j2π/3} + x_c e^{−j2π/3})`. The zero-sequence part
/// `(x_a + x_b + x_c)/3` is dropped: it produces no torque in a star-connected machine.
/// No errors, no panics. Source: MODEL.md §1; Krause et al. ch. 3.
#[inline]
pub fn clarke(x_a: f64, x_b: f64, x_c: f64) -> (f64, f64) {
    ((2.0 * x_a - x_b - x_c) / 3.0, (x_b - x_c) / SQRT3)
}

/// Inverse amplitude-invariant Clarke transform `(x_α, x_β)` → balanced phase values
/// `(x_a, x_b, x_c)` with `x_a + x_b + x_c = 0`, same unit as the input.
///
/// `x_a = x_α`, `x_b = −x_α/2 + (√3/2) x_β`, `x_c = −x_α/2 − (√3/2) x_β`; the inverse of
/// [`clarke`] on balanced (zero-sequence-free) sets. No errors, no panics.
/// Source: MODEL.md §1; Krause et al. ch. 3.
#[inline]
pub fn inverse_clarke(x_alpha: f64, x_beta: f64) -> (f64, f64, f64) {
    let h = 0.5 * SQRT3 * x_beta;
    (x_alpha, -0.5 * x_alpha + h, -0.5 * x_alpha - h)
}

/// Park transform `(x_α, x_β)` → `(x_d, x_q)` at the **electrical** angle `theta_e` \[rad\]:
/// `x_d + j x_q = (x_α + j x_β) e^{−jθ_e}`; same unit as the input.
///
/// No errors, no panics. Source: MODEL.md §1; Krause et al. ch. 3.
#[inline]
pub fn park(x_alpha: f64, x_beta: f64, theta_e: f64) -> (f64, f64) {
    let (s, c) = theta_e.sin_cos();
    (c * x_alpha + s * x_beta, -s * x_alpha + c * x_beta)
}

/// Inverse Park transform `(x_d, x_q)` → `(x_α, x_β)` at the **electrical** angle
/// `theta_e` \[rad\]: `x_α + j x_β = (x_d + j x_q) e^{jθ_e}`; same unit as the input.
///
/// No errors, no panics. Source: MODEL.md §1; Krause et al. ch. 3.
#[inline]
pub fn inverse_park(x_d: f64, x_q: f64, theta_e: f64) -> (f64, f64) {
    let (s, c) = theta_e.sin_cos();
    (c * x_d - s * x_q, s * x_d + c * x_q)
}

/// Period-mean factor of a voltage held in the stator frame, seen in dq:
/// `(1 − e^{−jφ})/(jφ)` as `(real, imaginary)`, dimensionless; `phi` \[rad\] is the
/// electrical angle the rotor turns within the period, `φ = ω_e h`.
///
/// Equals `(sin φ/φ, −(1 − cos φ)/φ)`; below `|φ| < 1e-8` the series
/// `(1 − φ²/6, −φ/2)` replaces the quotient (the limit at `φ = 0` is `(1, 0)`).
/// No errors, no panics (NaN in, NaN out). Source: MODEL.md §4 (stator-frame hold).
#[inline]
pub fn stator_hold_mean_factor(phi: f64) -> (f64, f64) {
    if phi.abs() < 1e-8 {
        (1.0 - phi * phi / 6.0, -0.5 * phi)
    } else {
        let half = 0.5 * phi;
        // 1 − cos φ = 2 sin²(φ/2) avoids the cancellation at small φ.
        (phi.sin() / phi, -2.0 * half.sin() * half.sin() / phi)
    }
}

/// dq currents `(i_d, i_q)` \[A, peak\], each of length N, from phase currents `i_a, i_b, i_c`
/// \[A, peak\] sampled at `t_k` and the **mechanical** angle `theta_m` \[rad\] at `t_k`.
///
/// `i_dq[k] = park(clarke(i_abc[k]), n_p θ_m[k])`. A zero-sequence component in the phase
/// currents is ignored.
///
/// # Errors
/// [`Error::LengthMismatch`] naming the first slice whose length differs from `i_a`'s.
/// Non-finite inputs propagate as non-finite outputs (validation happens in
/// [`Experiment::try_new`](crate::data::Experiment::try_new)).
///
/// Source: MODEL.md §1; Krause et al. ch. 3.
pub fn currents_to_dq(
    i_a: &[f64],
    i_b: &[f64],
    i_c: &[f64],
    theta_m: &[f64],
    n_p: u32,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let n = i_a.len();
    check_lengths(n, &[("ib", i_b), ("ic", i_c), ("theta_m", theta_m)])?;
    let n_p = f64::from(n_p);
    let (i_d, i_q) = (0..n)
        .map(|k| {
            let (al, be) = clarke(i_a[k], i_b[k], i_c[k]);
            park(al, be, n_p * theta_m[k])
        })
        .unzip();
    Ok((i_d, i_q))
}

/// Period-mean dq voltages `(u_d, u_q)` \[V, peak\], each of length N, from phase-to-neutral
/// voltages `u_a, u_b, u_c` \[V, peak\] that are period means over `[t_k, t_k + h)` of a
/// voltage held constant in the **stator** frame (what an inverter applies).
///
/// The stator-frame voltage `u_αβ[k] = clarke(u_abc[k])` is constant over the period while
/// the dq frame turns by `φ_k = n_p (w_m[k] + w_m[k+1])/2 · h` (mechanical speed `w_m`
/// \[rad/s\], sample time `h` \[s\]; `w_m[k]` alone for the last sample). Its dq period mean is
///
/// `u_dq[k] = park(u_αβ[k], n_p θ_m[k]) · (1 − e^{−jφ_k})/(jφ_k)`
///
/// (see [`stator_hold_mean_factor`]); `theta_m` \[rad\] is the **mechanical** angle at `t_k`.
/// This is exact when the speed is constant within the period. Do not use it for logs whose
/// phase voltages were computed from a dq voltage held over the step (gym-electric-motor):
/// there `park(clarke(u_abc[k]), θ_e[k])` alone is the logged dq voltage.
///
/// # Errors
/// [`Error::LengthMismatch`] naming the first slice whose length differs from `u_a`'s.
/// Non-finite inputs propagate as non-finite outputs.
///
/// Source: MODEL.md §4 ("In which frame is the voltage held?").
pub fn stator_held_voltages_to_dq(
    u_a: &[f64],
    u_b: &[f64],
    u_c: &[f64],
    theta_m: &[f64],
    w_m: &[f64],
    h: f64,
    n_p: u32,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let n = u_a.len();
    check_lengths(n, &[("ub", u_b), ("uc", u_c), ("theta_m", theta_m), ("w_m", w_m)])?;
    let n_p = f64::from(n_p);
    let (u_d, u_q) = (0..n)
        .map(|k| {
            let w = if k + 1 < n { 0.5 * (w_m[k] + w_m[k + 1]) } else { w_m[k] };
            let (al, be) = clarke(u_a[k], u_b[k], u_c[k]);
            let (d, q) = park(al, be, n_p * theta_m[k]);
            let (fr, fi) = stator_hold_mean_factor(n_p * w * h);
            (d * fr - q * fi, d * fi + q * fr)
        })
        .unzip();
    Ok((u_d, u_q))
}

fn check_lengths(n: usize, others: &[(&str, &[f64])]) -> Result<()> {
    for (column, v) in others {
        if v.len() != n {
            return Err(Error::LengthMismatch { column: (*column).to_string(), expected: n, found: v.len() });
        }
    }
    Ok(())
}
