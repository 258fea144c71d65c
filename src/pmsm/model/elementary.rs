//! Sine, cosine and hyperbolic tangent without a library call: straight-line code (no
//! branch, no table) whose loops over many values vectorise, within two ulps of the
//! system library's results. The library's functions are a call per value; the dead-time
//! check's error directions take one sine and cosine per sample and three tangents per
//! interval ([`crate::pmsm::model::inverter`]). [`sin_cos_small`] (the interval half angles of the
//! models) is the kernels without a tail, in its own order of operations.
//!
//! Sources: the reduction modulo π/2 and the kernels are fdlibm's (Sun Microsystems 1993,
//! `e_rem_pio2.c` medium case with its second step always taken, `k_sin.c`, `k_cos.c`; as
//! in musl), the exponential fdlibm's `e_exp.c`, and the tangent below 0.625 the rational
//! form of Cephes `tanh.c` (Moshier 1989).

/// Largest |x| \[rad\] that [`sin_cos_reduced`] takes: fdlibm's bound of its medium case
/// (high word 0x413921fb, just above 2²⁰ π/2 = 1 647 099.329), where n ≤ 2²⁰ and the
/// two-step reduction stays exact.
pub(crate) const REDUCE_LIMIT: f64 = 1_647_099.332_810_515_8;

/// Adding and subtracting `1.5 · 2⁵²` rounds a double below 2⁵¹ to an integer (ties to
/// even), whose low bits the sum's bit pattern then holds.
const TO_INT: f64 = 6_755_399_441_055_744.0;

/// The bit pattern of [`TO_INT`]: the sum's bits minus these are the integer.
const TO_INT_BITS: u64 = 0x4338_0000_0000_0000;

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

/// `(sin x, cos x)` for `|x| ≤` [`REDUCE_LIMIT`] (fdlibm: x reduced to `y ∈ [−π/4, π/4]`
/// with a tail, then `__kernel_sin`, `__kernel_cos` and the quadrant's swap and signs);
/// each within an ulp of the library's. Beyond the limit the result is not the sine: the
/// caller takes the library's there.
#[inline(always)]
pub(crate) fn sin_cos_reduced(x: f64) -> (f64, f64) {
    const INV_PIO2: f64 = std::f64::consts::FRAC_2_PI;
    // π/2 as two 33-bit parts and the tail of the second (e_rem_pio2.c: pio2_1, pio2_2, pio2_2t).
    const PIO2_1: f64 = 1.570_796_326_734_125_6;
    const PIO2_2: f64 = 6.077_100_506_303_966e-11;
    const PIO2_2T: f64 = 2.022_266_248_795_950_6e-21;
    let biased = x * INV_PIO2 + TO_INT;
    let quadrant = biased.to_bits().wrapping_sub(TO_INT_BITS) & 3;
    let n = biased - TO_INT;
    // x − n·pio2_1 is exact for |n| < 2²⁰; fdlibm's second step (good to 118 bits), which
    // it skips when the first (n·pio2_1t, 85 bits) already leaves no cancellation.
    let t = x - n * PIO2_1;
    let w = n * PIO2_2;
    let r = t - w;
    let w = n * PIO2_2T - ((t - r) - w);
    let y0 = r - w;
    let y1 = (r - y0) - w;
    let (s, c) = (kernel_sin(y0, y1), kernel_cos(y0, y1));
    let (a, b) = if quadrant & 1 == 1 { (c, s) } else { (s, c) };
    let sin = if quadrant & 2 == 2 { -a } else { a };
    let cos = if (quadrant + 1) & 2 == 2 { -b } else { b };
    (sin, cos)
}

/// fdlibm's `__kernel_sin(x, y, 1)`: sin(x + y) for |x| ≤ π/4, y the tail of x.
#[inline(always)]
fn kernel_sin(x: f64, y: f64) -> f64 {
    let z = x * x;
    let w = z * z;
    let r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    let v = z * x;
    x - ((z * (0.5 * y - v * r) - y) - v * S1)
}

/// fdlibm's `__kernel_cos(x, y)`: cos(x + y) for |x| ≤ π/4, y the tail of x.
#[inline(always)]
fn kernel_cos(x: f64, y: f64) -> f64 {
    let z = x * x;
    let w = z * z;
    let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    w + (((1.0 - w) - hz) + (z * r - x * y))
}

/// `tanh x` within two ulps of the library's: Cephes' rational form below |x| = 0.625,
/// `1 − 2/(e^{2|x|} + 1)` (the sign of x put back) up to 19.5, ±1 beyond, where
/// `1 − tanh|x| < 2e^{−39}` is below half an ulp of 1. NaN gives NaN.
#[inline(always)]
pub(crate) fn tanh(x: f64) -> f64 {
    // Cephes tanh.c: P and Q of x + x³ P(x²)/Q(x²), Q's leading coefficient 1.
    const P: [f64; 3] = [-9.643_991_794_250_522e-1, -9.928_772_310_019_185e1, -1.614_687_684_417_084_5e3];
    const Q: [f64; 3] = [1.128_116_784_916_329_3e2, 2.235_488_390_601_004_5e3, 4.844_063_053_251_255e3];
    let a = x.abs();
    let s = x * x;
    // The sign put back only matters for −0 (tanh has the sign of x).
    let small =
        (x + x * s * ((P[0] * s + P[1]) * s + P[2]) / (((s + Q[0]) * s + Q[1]) * s + Q[2])).copysign(x);
    let large = (1.0 - 2.0 / (exp_moderate(2.0 * a.min(19.5)) + 1.0)).copysign(x);
    if a < 0.625 {
        small
    } else if a < 19.5 {
        large
    } else if a.is_nan() {
        x
    } else {
        1.0f64.copysign(x)
    }
}

/// `e^y` for `0 ≤ y ≤ 39` (fdlibm `e_exp.c`: y = k ln 2 + r, a rational approximation of
/// e^r, the result scaled by 2^k), within an ulp.
#[inline(always)]
fn exp_moderate(y: f64) -> f64 {
    const LN2_HI: f64 = 6.931_471_803_691_238e-1;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    const INV_LN2: f64 = std::f64::consts::LOG2_E;
    const P1: f64 = 1.666_666_666_666_660_2e-1;
    const P2: f64 = -2.777_777_777_701_559_3e-3;
    const P3: f64 = 6.613_756_321_437_934e-5;
    const P4: f64 = -1.653_390_220_546_525_2e-6;
    const P5: f64 = 4.138_136_797_057_238_5e-8;
    let biased = y * INV_LN2 + TO_INT;
    let k = biased.to_bits().wrapping_sub(TO_INT_BITS);
    let kf = biased - TO_INT;
    let hi = y - kf * LN2_HI;
    let lo = kf * LN2_LO;
    let r = hi - lo;
    let t = r * r;
    let c = r - t * (P1 + t * (P2 + t * (P3 + t * (P4 + t * P5))));
    let e = 1.0 + (r * c / (2.0 - c) - lo + hi);
    e * f64::from_bits(k.wrapping_add(1023) << 52)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units of the last place of `b`.
    fn ulps(a: f64, b: f64) -> f64 {
        if a == b { 0.0 } else { (a - b).abs() / (b.abs() * f64::EPSILON).max(f64::MIN_POSITIVE) }
    }

    #[test]
    fn sine_and_cosine_are_within_an_ulp_of_the_library() {
        let mut worst: f64 = 0.0;
        // A dense sweep, the multiples of π/2 (the reduction's hard cases) and large angles.
        let xs = (-200_000..=200_000)
            .map(|k| f64::from(k) * 1e-3)
            .chain((-4000..4000).map(|k| f64::from(k) * std::f64::consts::FRAC_PI_2))
            .chain((0..20_000).map(|k| REDUCE_LIMIT * (f64::from(k) / 10_000.0 - 1.0)));
        for x in xs {
            let (s, c) = sin_cos_reduced(x);
            let (ls, lc) = x.sin_cos();
            // Relative (ulps of the library's value), except near a zero of the function,
            // where the absolute error in units of 1 counts (the library's own result there
            // is only as exact as x is a multiple of π/2).
            worst = worst.max(ulps(s, ls).min((s - ls).abs() / f64::EPSILON));
            worst = worst.max(ulps(c, lc).min((c - lc).abs() / f64::EPSILON));
        }
        assert!(worst <= 1.0, "{worst} ulp");
    }

    #[test]
    fn the_tangent_is_within_two_ulps_of_the_library() {
        let mut worst: f64 = 0.0;
        let xs = (-400_000..=400_000)
            .map(|k| f64::from(k) * 5e-5)
            .chain((-1000..=1000).map(|k| f64::from(k) * 1e-9))
            .chain([0.625, -0.625, 19.5, -19.5, 19.499_999_999_999_996, 1e300, -1e300, f64::INFINITY]);
        for x in xs {
            worst = worst.max(ulps(tanh(x), x.tanh()));
        }
        assert!(worst <= 2.0, "{worst} ulp");
        assert!(tanh(f64::NAN).is_nan());
        assert_eq!(tanh(-0.0).to_bits(), (-0.0f64).to_bits());
    }
}
