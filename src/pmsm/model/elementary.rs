//! Sine and cosine of the models' small half angles without a library call: the minimax
//! polynomials of fdlibm's kernels, straight-line code (no branch, no table, no argument
//! reduction) within an ulp of the system library's. The SPM and IPM steps take one per
//! interval ([`crate::pmsm::model::interval`]); the library's `sin_cos` is a call per value.
//!
//! Source: fdlibm (Sun Microsystems 1993), `k_sin.c` and `k_cos.c`, as in musl.

// fdlibm's minimax coefficients of `__kernel_sin` and `__kernel_cos`, each the shortest
// decimal of its double (S1 = 0xBFC55555_55555549 … C6 = 0xBDA8FAE9_BE8838D4 in k_sin.c,
// k_cos.c).
const S1: f64 = -0.166_666_666_666_666_32;
const S2: f64 = 0.008_333_333_333_322_49;
const S3: f64 = -1.984_126_982_985_795e-4;
const S4: f64 = 2.755_731_370_707_006_8e-6;
const S5: f64 = -2.505_076_025_340_686_3e-8;
const S6: f64 = 1.589_690_995_211_55e-10;
const C1: f64 = 0.041_666_666_666_666_6;
const C2: f64 = -0.001_388_888_888_887_411;
const C3: f64 = 2.480_158_728_947_673e-5;
const C4: f64 = -2.755_731_435_139_066_3e-7;
const C5: f64 = 2.087_572_321_298_175e-9;
const C6: f64 = -1.135_964_755_778_819_5e-11;

/// `(sin x, cos x)` for `|x| ≤ π/4` by the minimax polynomials of fdlibm's `__kernel_sin`
/// and `__kernel_cos` (Sun Microsystems 1993; as in musl's `__sin.c`, `__cos.c`): errors
/// below one ulp, no argument reduction and no branch, so a loop over intervals
/// vectorises (the library's `sin_cos` is a call per value).
#[inline(always)]
pub(crate) fn sin_cos_small(x: f64) -> (f64, f64) {
    let z = x * x;
    let w = z * z;
    let r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    let sin = x + z * x * (S1 + z * r);
    let rc = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let one_minus = 1.0 - hz;
    let cos = one_minus + (((1.0 - one_minus) - hz) + z * rc);
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units of the last place of `b`.
    fn ulps(a: f64, b: f64) -> f64 {
        if a == b { 0.0 } else { (a - b).abs() / (b.abs() * f64::EPSILON).max(f64::MIN_POSITIVE) }
    }

    #[test]
    fn sine_and_cosine_are_within_an_ulp_of_the_library_up_to_a_quarter_turn_over_two() {
        let mut worst: f64 = 0.0;
        for k in -100_000..=100_000 {
            let x = f64::from(k) * std::f64::consts::FRAC_PI_4 / 100_000.0;
            let ((s, c), (ls, lc)) = (sin_cos_small(x), x.sin_cos());
            // Relative, except near the sine's zero, where the absolute error counts.
            worst = worst.max(ulps(s, ls).min((s - ls).abs() / f64::EPSILON));
            worst = worst.max(ulps(c, lc));
        }
        assert!(worst <= 1.0, "{worst} ulp");
    }
}
