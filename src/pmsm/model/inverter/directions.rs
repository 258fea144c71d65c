//! How [`DeadTimeStream::directions`](super::DeadTimeStream::directions) takes its sines,
//! cosines and hyperbolic tangents, and its loops over a window of samples.
//!
//! The models take the system library's ([`Library`]): their error directions, hence their
//! estimates, are those of every earlier release to the bit, and a record made consistent
//! with them by iteration stays so. The dead-time check, a diagnostic that only reads a
//! fraction, takes [`Inline`]: straight-line code within two ulps of the library's
//! ([`crate::pmsm::model::elementary`]) in loops that vectorise, several times faster.

use crate::pmsm::log::transform::{clarke, inverse_clarke};
use crate::pmsm::model::elementary::{REDUCE_LIMIT, sin_cos_reduced, tanh};
use crate::pmsm::model::interval::C64;
use multiversion::multiversion;

/// Intervals per window of [`DeadTimeStream::directions`]: its scratch is on the stack.
pub(crate) const WINDOW: usize = 256;

/// The phase currents of a window, each phase's samples in a row.
pub(crate) type Phases = [[f64; WINDOW + 1]; 3];

/// Sines, cosines and smooth signs of [`super::DeadTimeStream::directions`].
pub(crate) trait Elementary {
    /// `(sin θ_e, cos θ_e)` of `θ_e = n_p θ_m` for every mechanical angle of `theta_m`
    /// \[rad\] into `out` (the same length).
    fn angles(n_p: f64, theta_m: &[f64], out: &mut [(f64, f64)]);

    /// The directions of the m = `out.len()` intervals between consecutive samples of the
    /// window (m + 1 phase currents \[A\] and angles), for the sign's width \[A\]:
    /// `−park(clarke(tanh(ī_a/w), tanh(ī_b/w), tanh(ī_c/w)), θ_e)` at each interval's start.
    fn signs(width: f64, phases: &Phases, sc: &[(f64, f64)], out: &mut [C64]);
}

/// The system library's `sin_cos` and `tanh` (the latter not called where it is ±1 to the
/// last bit, `|x| ≥ 19.5`: `1 − tanh|x| < 2e^{−39} < 2⁻⁵⁴`, below half an ulp of 1).
pub(crate) struct Library;

/// [`sin_cos_reduced`] (the library's beyond [`REDUCE_LIMIT`] and for NaN) and the inline
/// [`tanh`], vectorised (AVX-512 or AVX2 chosen at run time).
pub(crate) struct Inline;

impl Elementary for Library {
    fn angles(n_p: f64, theta_m: &[f64], out: &mut [(f64, f64)]) {
        for (o, t) in out.iter_mut().zip(theta_m) {
            *o = (n_p * t).sin_cos();
        }
    }

    fn signs(width: f64, phases: &Phases, sc: &[(f64, f64)], out: &mut [C64]) {
        let sign = |x: f64| if x.abs() >= 19.5 { x.signum() } else { x.tanh() };
        directions(width, phases, sc, out, sign);
    }
}

impl Elementary for Inline {
    fn angles(n_p: f64, theta_m: &[f64], out: &mut [(f64, f64)]) {
        inline_angles(n_p, theta_m, out);
    }

    fn signs(width: f64, phases: &Phases, sc: &[(f64, f64)], out: &mut [C64]) {
        inline_signs(width, phases, sc, out);
    }
}

#[multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn inline_angles(n_p: f64, theta_m: &[f64], out: &mut [(f64, f64)]) {
    for (o, t) in out.iter_mut().zip(theta_m) {
        *o = sin_cos_reduced(n_p * t);
    }
    if !theta_m.iter().all(|t| (n_p * t).abs() <= REDUCE_LIMIT) {
        for (o, t) in out.iter_mut().zip(theta_m) {
            let x = n_p * t;
            if x.abs() > REDUCE_LIMIT || x.is_nan() {
                *o = x.sin_cos();
            }
        }
    }
}

#[multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn inline_signs(width: f64, phases: &Phases, sc: &[(f64, f64)], out: &mut [C64]) {
    directions(width, phases, sc, out, tanh);
}

/// [`Elementary::signs`] with the smooth sign `sign` (inlined into the caller's loop).
#[inline(always)]
fn directions(width: f64, phases: &Phases, sc: &[(f64, f64)], out: &mut [C64], sign: impl Fn(f64) -> f64) {
    let m = out.len();
    // Each phase's current at both ends of every interval.
    let [a, b, c] = phases.each_ref().map(|p| p[..m].iter().zip(&p[1..=m]));
    let sign = |(x, y): (&f64, &f64)| -sign((0.5 * (x + y)) / width);
    for ((((o, &(s, co)), a), b), c) in out.iter_mut().zip(sc).zip(a).zip(b).zip(c) {
        let (alpha, beta) = clarke(sign(a), sign(b), sign(c));
        // park, with the angle's sine and cosine given.
        *o = C64::new(co * alpha + s * beta, -s * alpha + co * beta);
    }
}

/// The phase currents `(i_a, i_b, i_c)` \[A\] of each sample of a window from its dq
/// current \[A\] and angle (inverse Park with the sine and cosine given, then inverse
/// Clarke).
#[multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
pub(crate) fn phases(i_d: &[f64], i_q: &[f64], sc: &[(f64, f64)], out: &mut Phases) {
    let [a, b, c] = out;
    for (k, ((&(s, co), d), q)) in sc.iter().zip(i_d).zip(i_q).enumerate() {
        (a[k], b[k], c[k]) = inverse_clarke(co * d - s * q, s * d + co * q);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The check's inline functions give the models' directions to a few units of the last
    /// place of 1 (the directions are sums of signs of magnitude ≤ 4/3), on a window whose
    /// angles run past the reduction's limit and whose currents cross zero.
    #[test]
    fn inline_directions_are_the_library_directions_to_rounding() {
        let m = WINDOW;
        let theta_m: Vec<f64> =
            (0..=m).map(|k| 0.37 * k as f64 - 3.0 + if k > 200 { 1e6 } else { 0.0 }).collect();
        let i_d: Vec<f64> = (0..=m).map(|k| 3.0 * (0.05 * k as f64).sin()).collect();
        let i_q: Vec<f64> = (0..=m).map(|k| 12.0 * (0.011 * k as f64).cos() - 2.0).collect();
        fn run<E: Elementary>(theta_m: &[f64], i_d: &[f64], i_q: &[f64]) -> (Vec<(f64, f64)>, Vec<C64>) {
            let m = WINDOW;
            let mut sc = vec![(0.0, 0.0); m + 1];
            let mut p = [[0.0; WINDOW + 1]; 3];
            let mut out = vec![C64::default(); m];
            E::angles(4.0, theta_m, &mut sc);
            phases(i_d, i_q, &sc, &mut p);
            E::signs(0.8, &p, &sc, &mut out);
            (sc, out)
        }
        let (sc_lib, lib) = run::<Library>(&theta_m, &i_d, &i_q);
        let (sc_in, inline) = run::<Inline>(&theta_m, &i_d, &i_q);
        // Beyond the limit (4 · 1e6 rad) the inline angles are the library's.
        assert_eq!(sc_lib[201..], sc_in[201..]);
        let worst = lib.iter().zip(&inline).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(worst <= 8.0 * f64::EPSILON, "{worst:e}");
        assert!(lib.iter().any(|d| d.norm() > 0.5), "the signs are not all near zero");
    }
}
