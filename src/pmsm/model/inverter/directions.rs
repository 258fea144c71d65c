//! How [`DeadTimeStream::directions`](super::DeadTimeStream::directions) takes its sines,
//! cosines and hyperbolic tangents, and its loops over a window of samples.
//!
//! The models and the dead-time check take the system library's: the models' error
//! directions, hence their estimates, are those of every earlier release to the bit.

use crate::pmsm::log::transform::{clarke, inverse_clarke};
use crate::pmsm::model::interval::C64;
use multiversion::multiversion;

/// Intervals per window of [`DeadTimeStream::directions`](super::DeadTimeStream::directions): its scratch is on the stack.
pub(crate) const WINDOW: usize = 256;

/// The phase currents of a window, each phase's samples in a row.
pub(crate) type Phases = [[f64; WINDOW + 1]; 3];

/// `(sin θ_e, cos θ_e)` of `θ_e = n_p θ_m` for every mechanical angle of `theta_m` \[rad\]
/// into `out` (the same length), by the system library.
pub(crate) fn angles(n_p: f64, theta_m: &[f64], out: &mut [(f64, f64)]) {
    for (o, t) in out.iter_mut().zip(theta_m) {
        *o = (n_p * t).sin_cos();
    }
}

/// The directions of the m = `out.len()` intervals between consecutive samples of the
/// window (m + 1 phase currents \[A\] and angles), for the sign's width \[A\]:
/// `−park(clarke(tanh(ī_a/w), tanh(ī_b/w), tanh(ī_c/w)), θ_e)` at each interval's start;
/// the library's `tanh`, not called where it is ±1 to the last bit (`|x| ≥ 19.5`:
/// `1 − tanh|x| < 2e^{−39} < 2⁻⁵⁴`, below half an ulp of 1).
pub(crate) fn signs(width: f64, phases: &Phases, sc: &[(f64, f64)], out: &mut [C64]) {
    let sign = |x: f64| if x.abs() >= 19.5 { x.signum() } else { x.tanh() };
    directions(width, phases, sc, out, sign);
}

/// [`signs`] with the smooth sign `sign` (inlined into the caller's loop).
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
