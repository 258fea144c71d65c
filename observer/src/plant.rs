//! The observers' model of the machine over one period: the [`Plant`] trait and its exact
//! surface-magnet step in closed form, [`Spm`] (MODEL.md §4; `greybox::online`'s module
//! documentation derives it).

use crate::real::{Real, SQRT_2_3, cexpm1, rotation, stator_hold_start_sin};
use crate::types::{Hold, Sample, Settings};
use num_complex::Complex;

/// A step with its transition `Φ = ∂i[k+1]/∂i[k]` (row-major 2 × 2).
pub type Transition<T> = (Step<T>, [[T; 2]; 2]);

/// One period's step of the model from a state: the next current and its sensitivities,
/// all dq currents as complex numbers `d + j q` \[A\].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Step<T> {
    /// `i[k+1]` \[A\].
    pub next: Complex<T>,
    /// `∂i[k+1]/∂K_e` \[A/(V s/rad)\].
    pub phi_k: Complex<T>,
    /// `∂i[k+1]/∂R_s` \[A/Ω\].
    pub phi_r: Complex<T>,
    /// The MRAS's `K_e` law direction: `φ_K`, or for the relay law `φ_K/|ω_m|`.
    pub psi_k: Complex<T>,
}

/// The machine's exact one-period step with its sensitivities to `K_e` and `R_s`.
/// Implemented here for surface magnets ([`Spm`]); the `greybox` crate implements it for
/// a salient machine by its augmented matrix exponential.
pub trait Plant<T: Real> {
    /// Why a step fails.
    type Error;

    /// The step from the current `x` \[A\] at `k_e` \[V s/rad\], `r_s` \[Ω\] with the voltage
    /// and speed of `s`; `relay`: `psi_k` for the relay law.
    ///
    /// # Errors
    /// The model's.
    fn step(&self, x: Complex<T>, k_e: T, r_s: T, s: &Sample<T>, relay: bool)
    -> Result<Step<T>, Self::Error>;

    /// [`Plant::step`] (`psi_k = phi_k`) and the step's transition `Φ = ∂i[k+1]/∂i[k]`
    /// (row-major, `[[∂d/∂d, ∂d/∂q], [∂q/∂d, ∂q/∂q]]`); by default from the step's
    /// linearity in the current (two more steps).
    ///
    /// # Errors
    /// The model's.
    fn step_transition(
        &self,
        x: Complex<T>,
        k_e: T,
        r_s: T,
        s: &Sample<T>,
    ) -> Result<Transition<T>, Self::Error> {
        let st = self.step(x, k_e, r_s, s, false)?;
        let d = self.step(x + Complex::new(T::one(), T::zero()), k_e, r_s, s, false)?.next - st.next;
        let q = self.step(x + Complex::new(T::zero(), T::one()), k_e, r_s, s, false)?.next - st.next;
        Ok((st, [[d.re, q.re], [d.im, q.im]]))
    }
}

/// The surface-magnet machine's exact step (MODEL.md §4), in closed form,
/// `i[k+1] = a i[k] + b (u − j emf K_e)` with `a = e^{−z h/L_s}`, `z = R_s + j ω_e L_s`, `b = (1 − a)/z`
/// for the dq hold, and the stator hold's exact forced term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spm<T> {
    n_p: u32,
    l_s: T,
    h: T,
    hold: Hold,
}

impl<T: Real> Spm<T> {
    /// The step of the machine of `settings` (`n_p`, `l_s`, `h`, `hold`).
    pub fn new(settings: &Settings<T>) -> Self {
        Self { n_p: settings.n_p, l_s: settings.l_s, h: settings.h, hold: settings.hold }
    }

    /// The step and its factor `a` of the current (`i[k+1] = a x + …`).
    #[inline]
    pub fn step_factor(
        &self,
        x: Complex<T>,
        k_e: T,
        r_s: T,
        s: &Sample<T>,
        relay: bool,
    ) -> (Step<T>, Complex<T>) {
        let (l, h) = (self.l_s, self.h);
        let hl = h / l;
        let w_e = T::c(f64::from(self.n_p)) * s.w_m;
        let rot = rotation(w_e * h);
        let d = (-r_s * hl).exp();
        let a = rot * d;
        let w = Complex::new(r_s, w_e * l) * hl;
        let (p1, p1_prime) = phi1_pair(w);
        let b = p1 * hl;
        let b_r = p1_prime * (hl * hl);
        let sqrt_2_3 = T::c(SQRT_2_3);
        let je = Complex::new(T::zero(), sqrt_2_3 * s.w_m * k_e);
        let u = Complex::new(s.u_d, s.u_q);
        let (forced, forced_r) = match self.hold {
            Hold::Dq => (b * (u - je), b_r * (u - je)),
            Hold::Stator => {
                // u₀ e^{−jφ} (1 − e^{−R h/L})/R, the exact stator-hold term (MODEL.md §4);
                // sin φ from the rotation (`rot.im = −sin φ`).
                let u_s = stator_hold_start_sin(u, w_e * h, -rot.im) * rot;
                let (q1, q1_prime) = phi1_pair_real(r_s * hl);
                (u_s * (q1 * hl) - b * je, u_s * (q1_prime * hl * hl) - b_r * je)
            }
        };
        let next = a * x + forced;
        let phi_k = -b * Complex::new(T::zero(), sqrt_2_3 * s.w_m);
        let psi_k = if relay {
            -b * Complex::new(T::zero(), sqrt_2_3 * if s.w_m < T::zero() { -T::one() } else { T::one() })
        } else {
            phi_k
        };
        let phi_r = a * (-hl) * x + forced_r;
        (Step { next, phi_k, phi_r, psi_k }, a)
    }
}

impl<T: Real> Plant<T> for Spm<T> {
    type Error = core::convert::Infallible;

    #[inline]
    fn step(
        &self,
        x: Complex<T>,
        k_e: T,
        r_s: T,
        s: &Sample<T>,
        relay: bool,
    ) -> Result<Step<T>, Self::Error> {
        Ok(self.step_factor(x, k_e, r_s, s, relay).0)
    }

    /// In closed form: `Φ` is the rotation and decay `a`.
    #[inline]
    fn step_transition(
        &self,
        x: Complex<T>,
        k_e: T,
        r_s: T,
        s: &Sample<T>,
    ) -> Result<Transition<T>, Self::Error> {
        let (st, a) = self.step_factor(x, k_e, r_s, s, false);
        Ok((st, [[a.re, -a.im], [a.im, a.re]]))
    }
}

/// `(φ₁(w), φ₁'(w))` ([`phi1`], [`phi1_prime`]) from one `|w|` and one `e^{−w} − 1`: the
/// same numbers as the two functions, to the bit.
#[inline]
pub fn phi1_pair<T: Real>(w: Complex<T>) -> (Complex<T>, Complex<T>) {
    let norm = w.norm();
    if norm < T::c(1e-3) {
        return (phi1_series(w), phi1_prime_series(w));
    }
    let em = cexpm1(-w);
    let p1 = -em / w;
    if norm < T::c(1e-2) {
        return (p1, phi1_prime_series(w));
    }
    (p1, (em * (w + T::one()) + w) / (w * w))
}

/// [`phi1_pair`] of a real `x` (`w = x + 0j`), the real parts, with one `expm1` and no
/// sine: the complex functions' numbers to the bit (their imaginary parts are zeros, so
/// `e^{−x} − 1` is `expm1(−x)` exactly and each complex division is
/// `(a x)/(x x)`, `(a x²)/(x² x²)`).
#[inline]
pub fn phi1_pair_real<T: Real>(x: T) -> (T, T) {
    let w = Complex::new(x, T::zero());
    let norm = x.abs();
    if norm < T::c(1e-3) {
        return (phi1_series(w).re, phi1_prime_series(w).re);
    }
    let em = (-x).exp_m1();
    let p1 = (-em * x) / (x * x);
    if norm < T::c(1e-2) {
        return (p1, phi1_prime_series(w).re);
    }
    let xx = x * x;
    (p1, ((em * (x + T::one()) + x) * xx) / (xx * xx))
}

/// `1 − w/2 + w²/6 − w³/24 + w⁴/120`: [`phi1`] below `|w| = 1e-3`, error below `|w|⁵/720`.
#[inline]
fn phi1_series<T: Real>(w: Complex<T>) -> Complex<T> {
    let c = |v: f64| Complex::new(T::c(v), T::zero());
    c(1.0) + w * (c(-0.5) + w * (c(1.0 / 6.0) + w * (c(-1.0 / 24.0) + w / T::c(120.0))))
}

/// `−1/2 + w/3 − w²/8 + w³/30 − w⁴/144 + w⁵/840`: [`phi1_prime`] below `|w| = 1e-2`, error
/// below `|w|⁶/5760`.
#[inline]
fn phi1_prime_series<T: Real>(w: Complex<T>) -> Complex<T> {
    let c = |v: f64| Complex::new(T::c(v), T::zero());
    c(-0.5)
        + w * (c(1.0 / 3.0)
            + w * (c(-1.0 / 8.0) + w * (c(1.0 / 30.0) + w * (c(-1.0 / 144.0) + w / T::c(840.0)))))
}

/// `(1 − e^{−w})/w`, with its limit 1 at w = 0 and no cancellation near it.
#[inline]
pub fn phi1<T: Real>(w: Complex<T>) -> Complex<T> {
    if w.norm() < T::c(1e-3) {
        return phi1_series(w);
    }
    -cexpm1(-w) / w
}

/// `d/dw (1 − e^{−w})/w = ((1 + w) e^{−w} − 1)/w²`, limit −1/2 at w = 0.
#[inline]
pub fn phi1_prime<T: Real>(w: Complex<T>) -> Complex<T> {
    if w.norm() < T::c(1e-2) {
        return phi1_prime_series(w);
    }
    (cexpm1(-w) * (w + T::one()) + w) / (w * w)
}

#[cfg(test)]
mod tests {
    use super::*;

    type C = Complex<f64>;

    #[test]
    fn series_meet_closed_forms_at_their_switch() {
        for w in [C::new(1.1e-3, 0.2e-3), C::new(0.0, 9e-4), C::new(0.011, -0.003), C::new(0.0, 0.0099)] {
            // The series of φ₁ holds below |w| = 1e-3, with error |w|⁵/720.
            let closed = -cexpm1(-w) / w;
            let series = C::new(1.0, 0.0) + w * (-0.5 + w * (1.0 / 6.0 + w * (-1.0 / 24.0 + w / 120.0)));
            assert!((closed - series).norm() < 1e-14 + w.norm().powi(5) / 720.0 * 1.01, "{w}");
            let closed_p = (cexpm1(-w) * (w + 1.0) + w) / (w * w);
            let series_p = C::new(-0.5, 0.0)
                + w * (1.0 / 3.0 + w * (-1.0 / 8.0 + w * (1.0 / 30.0 + w * (-1.0 / 144.0 + w / 840.0))));
            assert!((closed_p - series_p).norm() < 1e-11, "{w}");
            let d = 1e-5;
            let fd = (phi1(w + d) - phi1(w - d)) / (2.0 * d);
            assert!((phi1_prime(w) - fd).norm() < 1e-8, "{w}");
        }
    }

    /// The shared forms give the separate functions' numbers to the bit, on both sides of
    /// the series' switches (`std`: the C library's functions; alone: the `libm` crate's).
    #[test]
    fn the_shared_forms_are_the_functions_to_the_bit() {
        let bits = |c: C| (c.re.to_bits(), c.im.to_bits());
        let mut x = 1e-7;
        while x < 3.0 {
            for w in [C::new(x, 0.3 * x), C::new(x, -2.0 * x), C::new(0.1 * x, x)] {
                let (p, q) = phi1_pair(w);
                assert_eq!((bits(p), bits(q)), (bits(phi1(w)), bits(phi1_prime(w))), "{w}");
            }
            let (p, q) = phi1_pair_real(x);
            let w = C::new(x, 0.0);
            assert_eq!((p.to_bits(), q.to_bits()), (phi1(w).re.to_bits(), phi1_prime(w).re.to_bits()), "{x}");
            for phi in [x, -x] {
                let u = C::new(3.0, -40.0);
                let fast = crate::real::stator_hold_start_sin(u, phi, -rotation(phi).im);
                assert_eq!(bits(fast), bits(crate::real::stator_hold_start(u, phi)), "{phi}");
            }
            x *= 1.37;
        }
    }
}
