//! Sine and cosine of the models' small half angles without a library call: the minimax
//! polynomials of fdlibm's kernels, straight-line code (no branch, no table, no argument
//! reduction) within an ulp of the system library's. The SPM and IPM steps take one per
//! interval ([`crate::pmsm::model::interval`]); the library's `sin_cos` is a call per value.
//! The switching-resolved step's pieces ([`crate::pmsm::model::pwm`]) take their short
//! rotations from the same kernels, their short decays and the smooth leg state its
//! arctangents far from zero current from Taylor series (Abramowitz & Stegun 4.2.1 and
//! 4.4.42), the library's functions elsewhere.
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

/// `e^x` \[1\] of `x` \[1\]: for `|x| ≤ 1/8` (a PWM piece's decay `μτ`) its Taylor
/// polynomial to `x¹³` (remainder below `10⁻²³`), otherwise the library's.
#[inline(always)]
pub(crate) fn exp(x: f64) -> f64 {
    if x.abs() > 0.125 {
        return x.exp();
    }
    // 1/k!, k = 13 … 0.
    const C: [f64; 14] = {
        let mut c = [1.0; 14];
        let mut k = 1;
        while k < 14 {
            c[13 - k] = c[14 - k] / k as f64;
            k += 1;
        }
        c
    };
    C.iter().fold(0.0, |p, c| p * x + c)
}

/// `(sin x, cos x)` of `x` \[rad\]: [`sin_cos_small`] for `|x| ≤ π/4` (a PWM piece's
/// rotation `ω_e τ`), otherwise the library's.
#[inline(always)]
pub(crate) fn sin_cos(x: f64) -> (f64, f64) {
    if x.abs() > std::f64::consts::FRAC_PI_4 { x.sin_cos() } else { sin_cos_small(x) }
}

/// `atan x` \[rad\]: for `|x| ≥ 16` (a leg's current far outside the smooth leg state's
/// width) `±π/2 − atan(1/x)` with `atan z` by its Taylor series to `z¹³` (remainder below
/// `10⁻¹⁹`), otherwise the library's.
#[inline(always)]
pub(crate) fn atan(x: f64) -> f64 {
    if x.abs() < 16.0 {
        return x.atan();
    }
    // (−1)^k/(2k + 1), k = 6 … 0: atan z = z Σ (−1)^k z^{2k}/(2k + 1).
    const C: [f64; 7] = [1.0 / 13.0, -1.0 / 11.0, 1.0 / 9.0, -1.0 / 7.0, 1.0 / 5.0, -1.0 / 3.0, 1.0];
    let z = 1.0 / x;
    let z2 = z * z;
    std::f64::consts::FRAC_PI_2.copysign(x) - z * C.iter().fold(0.0, |p, c| p * z2 + c)
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

    /// The short series against the library's functions, on and around their ranges:
    /// within two units in the last place (the library's are within one).
    #[test]
    fn the_short_series_are_the_library_functions() {
        for k in -2000..=2000 {
            let x = f64::from(k) * 1.3e-4;
            assert!(ulps(exp(x), x.exp()) <= 2.0, "exp {x}");
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            assert!(ulps(s, s0) <= 2.0 && ulps(c, c0) <= 2.0, "sin_cos {x}: {s} {c} vs {s0} {c0}");
            let y = 16.0 * (1.0 + f64::from(k).abs() * 1e-3).powi(3) * if k < 0 { -1.0 } else { 1.0 };
            assert!(ulps(atan(y), y.atan()) <= 2.0, "atan {y}");
        }
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
    }
}
