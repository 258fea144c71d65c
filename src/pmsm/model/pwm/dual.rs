//! The scalar of the switching-resolved step: `f64` for the plain step, and a dual number
//! with [`N`] derivatives for the step with sensitivities (forward-mode differentiation,
//! Griewank & Walther, *Evaluating Derivatives*, 2nd ed., ch. 3). Every derivative of the
//! step, including those through the switching instants that the dead time moves, is then
//! the exact derivative of the arithmetic that computes the step, to rounding: no
//! finite-difference step, no separate hand-written sensitivity recursion to keep in step
//! with the model.

use crate::pmsm::model::elementary::{atan, exp, sin_cos};
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Derivatives a [`Dual`] carries: the most parameters of a PWM-resolved model (`r_s, l_d,
/// l_q, k_e, t_d, u_th, i_w`), padded.
pub(crate) const N: usize = 8;

/// A value and its derivatives with respect to up to [`N`] parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Dual {
    pub v: f64,
    pub d: [f64; N],
}

impl Dual {
    /// The value `v` with derivatives `d`.
    pub(crate) fn new(v: f64, d: [f64; N]) -> Self {
        Self { v, d }
    }
    /// Parameter `j` of value `v`: derivative 1 with respect to itself.
    pub(crate) fn seed(v: f64, j: usize) -> Self {
        let mut d = [0.0; N];
        if j < N {
            d[j] = 1.0;
        }
        Self { v, d }
    }
    /// `f(v)` with derivative `f'(v)`: the chain rule.
    #[inline(always)]
    fn chain(self, f: f64, df: f64) -> Self {
        Self { v: f, d: self.d.map(|x| df * x) }
    }
}

/// The arithmetic the step needs, for `f64` and [`Dual`].
pub(crate) trait Scalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Send
    + Sync
{
    /// A constant (no derivatives).
    fn cst(v: f64) -> Self;
    /// The value.
    fn val(self) -> f64;
    fn exp(self) -> Self;
    fn sqrt(self) -> Self;
    fn atan(self) -> Self;
    fn sin_cos(self) -> (Self, Self);
    /// Whether the value and every derivative are 0.
    fn is_zero(self) -> bool;
    /// The order by value, then (ties) by the derivatives, lexicographically: an instant
    /// that moves later with a parameter comes after a fixed one of the same value.
    fn order(self, o: Self) -> std::cmp::Ordering;
    fn sinh_cosh(self) -> (Self, Self) {
        let e = self.exp();
        let inv = Self::cst(1.0) / e;
        ((e - inv) * 0.5, (e + inv) * 0.5)
    }
}

impl Scalar for f64 {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn val(self) -> f64 {
        self
    }
    #[inline(always)]
    fn exp(self) -> Self {
        exp(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn atan(self) -> Self {
        atan(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        sin_cos(self)
    }
    #[inline(always)]
    fn is_zero(self) -> bool {
        self == 0.0
    }
    #[inline(always)]
    fn order(self, o: Self) -> std::cmp::Ordering {
        self.total_cmp(&o)
    }
}

impl Scalar for Dual {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        Self { v, d: [0.0; N] }
    }
    #[inline(always)]
    fn val(self) -> f64 {
        self.v
    }
    #[inline(always)]
    fn exp(self) -> Self {
        let e = exp(self.v);
        self.chain(e, e)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s)
    }
    #[inline(always)]
    fn atan(self) -> Self {
        self.chain(atan(self.v), 1.0 / (1.0 + self.v * self.v))
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = sin_cos(self.v);
        (self.chain(s, c), self.chain(c, -s))
    }
    #[inline(always)]
    fn is_zero(self) -> bool {
        self.v == 0.0 && self.d.iter().all(|d| *d == 0.0)
    }
    #[inline(always)]
    fn order(self, o: Self) -> std::cmp::Ordering {
        self.v.total_cmp(&o.v).then_with(|| {
            self.d
                .iter()
                .zip(&o.d)
                .map(|(a, b)| a.total_cmp(b))
                .find(|c| c.is_ne())
                .unwrap_or(std::cmp::Ordering::Equal)
        })
    }
}

impl Add for Dual {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self { v: self.v + o.v, d: std::array::from_fn(|j| self.d[j] + o.d[j]) }
    }
}
impl Sub for Dual {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self { v: self.v - o.v, d: std::array::from_fn(|j| self.d[j] - o.d[j]) }
    }
}
impl Mul for Dual {
    type Output = Self;
    // The product rule: (uv)' = u'v + uv'.
    #[allow(clippy::suspicious_arithmetic_impl)]
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self { v: self.v * o.v, d: std::array::from_fn(|j| self.d[j] * o.v + self.v * o.d[j]) }
    }
}
impl Div for Dual {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let v = self.v * inv;
        Self { v, d: std::array::from_fn(|j| (self.d[j] - v * o.d[j]) * inv) }
    }
}
impl Neg for Dual {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self { v: -self.v, d: self.d.map(|x| -x) }
    }
}
impl Add<f64> for Dual {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: f64) -> Self {
        Self { v: self.v + o, d: self.d }
    }
}
impl Sub<f64> for Dual {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: f64) -> Self {
        Self { v: self.v - o, d: self.d }
    }
}
impl Mul<f64> for Dual {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        Self { v: self.v * o, d: self.d.map(|x| x * o) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each rule against a central difference of the `f64` arithmetic.
    #[test]
    fn the_dual_rules_are_the_derivatives() {
        let f = |x: Dual| {
            let (s, c) = (x * 0.7).sin_cos();
            (x.exp() * s + c / (x + 2.0) - x.sqrt() * x.atan()) * (-x) + x.sinh_cosh().0 - 1.5
        };
        let g = |x: f64| f(Dual::cst(x)).v;
        for x in [0.3, 1.1, 2.7] {
            let d = f(Dual::seed(x, 2)).d[2];
            let h = 1e-6;
            let fd = (g(x + h) - g(x - h)) / (2.0 * h);
            assert!((d - fd).abs() < 1e-7 * (1.0 + fd.abs()), "{x}: {d} vs {fd}");
        }
    }
}
