//! How [`DeadTimeStream::directions`](super::DeadTimeStream::directions) takes its sines,
//! cosines and hyperbolic tangents, and its loops over a window of samples.
//!
//! The models take the system library's: their error directions, hence their estimates,
//! are those of every earlier release to the bit. The dead-time check, whose directions
//! only decide whether a warning is given and the percentage it prints, takes `wide`'s
//! vectorised sine, cosine and exponential ([`angles_check`], [`signs_check`]: within a few
//! units in the last place of the library's, a fifth of its time).

use crate::pmsm::log::transform::{clarke, inverse_clarke};
use crate::pmsm::model::interval::C64;
use multiversion::multiversion;
use wide::f64x4;

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

/// Largest `|θ_e|` \[rad\] [`angles_check`] reduces itself: `wide`'s three-part Cody–Waite
/// reduction by π/2 is exact while the quadrant count times its leading part (25 bits)
/// fits a double's 53 (to about 4·10⁸ rad); larger angles take the library's reduction.
const CHECK_ANGLE_LIMIT: f64 = 1.0e6;

/// [`angles`] for the dead-time check: `wide`'s vectorised `sin_cos` (Agner Fog's vector
/// class library; about 1 ulp) four angles at a time, the library's for the tail and for
/// any four with an angle beyond [`CHECK_ANGLE_LIMIT`].
pub(crate) fn angles_check(n_p: f64, theta_m: &[f64], out: &mut [(f64, f64)]) {
    let mut t4 = theta_m.chunks_exact(4);
    let mut o4 = out.chunks_exact_mut(4);
    for (t, o) in (&mut t4).zip(&mut o4) {
        let x = f64x4::from([n_p * t[0], n_p * t[1], n_p * t[2], n_p * t[3]]);
        if x.abs().to_array().iter().all(|a| *a <= CHECK_ANGLE_LIMIT) {
            let (s, c) = x.sin_cos();
            for ((o, s), c) in o.iter_mut().zip(s.to_array()).zip(c.to_array()) {
                *o = (s, c);
            }
        } else {
            angles(n_p, t, o);
        }
    }
    angles(n_p, t4.remainder(), o4.into_remainder());
}

/// `tanh x` of four lanes by `wide`'s exponential: `1 − 2/(e^{2|x|} + 1)` with x's sign,
/// `|x|` clamped at 20 (`tanh 20` is 1 to the last bit). Absolute error a few ulps of 1
/// (so relatively larger for `|x| ≪ 1`, where the direction is itself small). A NaN lane
/// gives ±1, where the library's gives NaN: the logs' currents are finite (the reader
/// refuses others).
#[inline(always)]
fn tanh4(x: f64x4) -> f64x4 {
    let a = x.abs().min(f64x4::splat(20.0));
    let one = f64x4::splat(1.0);
    (one - f64x4::splat(2.0) / ((a + a).exp() + one)).copysign(x)
}

/// [`signs`] for the dead-time check: the smooth sign by [`tanh4`], four intervals at a
/// time, then the Clarke and Park transforms as [`signs`] does.
///
/// # Panics
/// When `out` is longer than [`WINDOW`].
pub(crate) fn signs_check(width: f64, phases: &Phases, sc: &[(f64, f64)], out: &mut [C64]) {
    let m = out.len();
    let mut s = [[0.0; WINDOW]; 3];
    for (p, s) in phases.iter().zip(&mut s) {
        // Lanes past m read the window's zero padding and are not used.
        for k in (0..m).step_by(4) {
            let x = |j: usize| f64x4::from([p[j], p[j + 1], p[j + 2], p[j + 3]]);
            let mean = f64x4::splat(0.5) * (x(k) + x(k + 1)) / f64x4::splat(width);
            s[k..k + 4].copy_from_slice(&(-tanh4(mean)).to_array());
        }
    }
    for (k, (o, &(sn, co))) in out.iter_mut().zip(sc).enumerate() {
        let (alpha, beta) = clarke(s[0][k], s[1][k], s[2][k]);
        *o = C64::new(co * alpha + sn * beta, -sn * alpha + co * beta);
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The check's vectorised functions against the library's: sines and cosines within
    /// 4e-16 of them over angles up to 4·10⁴ rad (and the library's own beyond
    /// [`CHECK_ANGLE_LIMIT`]), the directions within 2e-15, the tail of a window included.
    #[test]
    fn the_checks_directions_are_the_librarys_within_a_few_ulps() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        // Angles to 4·10⁵ rad reduced by `wide`, 1e12 rad by the library's fallback (beyond
        // `wide`'s exact reduction).
        for (n, scale) in [(WINDOW + 1, 1e4), (131, 6.0), (64, 1e5), (4, 1e7), (8, 1e12), (3, 1.0)] {
            let theta: Vec<f64> = (0..n).map(|_| rng.random_range(-scale..scale)).collect();
            let (mut a, mut b) = (vec![(0.0, 0.0); n], vec![(0.0, 0.0); n]);
            angles(4.0, &theta, &mut a);
            angles_check(4.0, &theta, &mut b);
            for (x, y) in a.iter().zip(&b) {
                assert!((x.0 - y.0).abs() <= 4e-16 && (x.1 - y.1).abs() <= 4e-16, "{x:?} {y:?}");
            }
            let mut phases = [[0.0; WINDOW + 1]; 3];
            // Currents of a few widths around zero, where tanh is not ±1, and beyond.
            for p in &mut phases {
                for v in &mut p[..n] {
                    *v = rng.random_range(-30.0..30.0) * if rng.random_bool(0.2) { 1e-9 } else { 1.0 };
                }
            }
            let m = n - 1;
            let (mut d, mut e) = (vec![C64::default(); m], vec![C64::default(); m]);
            signs(1.5, &phases, &a, &mut d);
            signs_check(1.5, &phases, &a, &mut e);
            for (x, y) in d.iter().zip(&e) {
                assert!((x - y).norm() <= 2e-15, "{x} {y}");
            }
        }
        // tanh itself: the sign at ±19.5 widths and beyond, and tiny arguments.
        for x in [0.0, -0.0, 1e-300, 1e-8, -0.3, 0.5493, 1.0, -3.7, 19.4, 19.5, -40.0, 1e300] {
            let t = tanh4(f64x4::splat(x)).to_array()[0];
            assert!((t - x.tanh()).abs() <= 4.5e-16, "tanh {x}: {t} against {}", x.tanh());
        }
    }
}
