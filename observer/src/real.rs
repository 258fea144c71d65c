//! The scalar the observers compute in: `f32` or `f64`.

use num_complex::Complex;
use num_traits::Float;

/// A floating-point scalar, `f32` or `f64`, with the elementary functions of `num-traits`
/// (the `libm` crate without the feature `std`, the host's C library with it).
pub trait Real: Float + Default + core::fmt::Debug + 'static {
    /// The constant `x` in this precision (rounded to nearest for `f32`).
    fn c(x: f64) -> Self;
}

impl Real for f64 {
    #[inline(always)]
    fn c(x: f64) -> f64 {
        x
    }
}

impl Real for f32 {
    #[inline(always)]
    fn c(x: f64) -> f32 {
        x as f32
    }
}

/// `√(2/3)`: back-EMF per `K_e` and mechanical speed (MODEL.md §2).
pub const SQRT_2_3: f64 = 0.816_496_580_927_726;

/// `e^w − 1` of a complex `w` without cancellation near 0: `Re = expm1(Re w) cos(Im w) −
/// 2 sin²(Im w / 2)`, `Im = e^{Re w} sin(Im w)`.
#[inline]
pub fn cexpm1<T: Real>(w: Complex<T>) -> Complex<T> {
    let (s, c) = w.im.sin_cos();
    let half = (T::c(0.5) * w.im).sin();
    Complex::new(w.re.exp_m1() * c - T::c(2.0) * half * half, w.re.exp() * s)
}

/// Rotation of the dq frame over one period, `e^{−jφ}` with `φ = ω_e h` \[rad\].
#[inline]
pub fn rotation<T: Real>(phi: T) -> Complex<T> {
    Complex::new(phi.cos(), -phi.sin())
}

/// Start-of-period dq voltage `u₀ = ū jφ/(1 − e^{−jφ})` of a stator-held voltage whose dq
/// period mean is `ū` \[V\] (MODEL.md §4); the limit φ → 0 is `ū`.
#[inline]
pub fn stator_hold_start<T: Real>(mean: Complex<T>, phi: T) -> Complex<T> {
    if phi.abs() < T::c(1e-8) {
        // jφ/(1 − e^{−jφ}) = 1 + jφ/2 − φ²/12 + O(φ⁴)
        return mean * Complex::new(T::one() - phi * phi / T::c(12.0), T::c(0.5) * phi);
    }
    let denom = -cexpm1(Complex::new(T::zero(), -phi));
    mean * Complex::new(T::zero(), phi) / denom
}

/// [`stator_hold_start`] given `sin φ` (the rotation's, at hand): `1 − e^{−jφ} = 2 sin²(φ/2)
/// + j sin φ`, one sine instead of a complex `expm1`. The same number to the bit where the
/// sine is odd (`sin(−x) = −sin x`, as in the C library and the `libm` crate): the complex
/// `expm1` of `−jφ` takes `e^0 − 1 = 0` and `e^0 = 1` exactly.
#[inline]
pub fn stator_hold_start_sin<T: Real>(mean: Complex<T>, phi: T, sin_phi: T) -> Complex<T> {
    if phi.abs() < T::c(1e-8) {
        return mean * Complex::new(T::one() - phi * phi / T::c(12.0), T::c(0.5) * phi);
    }
    let half = (T::c(0.5) * -phi).sin();
    let denom = Complex::new(T::c(2.0) * half * half, sin_phi);
    mean * Complex::new(T::zero(), phi) / denom
}
