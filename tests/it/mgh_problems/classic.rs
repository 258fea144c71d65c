//! MGH problems with closed-form residuals: Rosenbrock (MGH 1), Freudenstein-Roth (2),
//! Jennrich-Sampson (6), helical valley (7), Box three-dimensional (12), Powell singular
//! (13), Brown-Dennis (16); MINPACK numbers 4, 7, 13, 5, 12, 6, 14.

use super::MghProblem;
use std::f64::consts::PI;

/// Rosenbrock: `r = (10(x₂ − x₁²), 1 − x₁)`; zero residual at (1, 1).
pub struct Rosenbrock;

impl MghProblem for Rosenbrock {
    fn name(&self) -> &str {
        "Rosenbrock"
    }
    fn m(&self) -> usize {
        2
    }
    fn n(&self) -> usize {
        2
    }
    fn start(&self) -> Vec<f64> {
        vec![-1.2, 1.0]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        r[0] = 10.0 * (x[1] - x[0] * x[0]);
        r[1] = 1.0 - x[0];
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        j.copy_from_slice(&[-20.0 * x[0], 10.0, -1.0, 0.0]);
    }
}

/// Helical valley: `r = (10(x₃ − 10θ), 10(√(x₁² + x₂²) − 1), x₃)`, `θ` the angle of
/// (x₁, x₂) in turns; zero residual at (1, 0, 0).
pub struct HelicalValley;

impl MghProblem for HelicalValley {
    fn name(&self) -> &str {
        "Helical valley"
    }
    fn m(&self) -> usize {
        3
    }
    fn n(&self) -> usize {
        3
    }
    fn start(&self) -> Vec<f64> {
        vec![-1.0, 0.0, 0.0]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        let tpi = 2.0 * PI;
        let theta = if x[0] > 0.0 {
            (x[1] / x[0]).atan() / tpi
        } else if x[0] < 0.0 {
            (x[1] / x[0]).atan() / tpi + 0.5
        } else {
            0.25_f64.copysign(x[1])
        };
        r[0] = 10.0 * (x[2] - 10.0 * theta);
        r[1] = 10.0 * ((x[0] * x[0] + x[1] * x[1]).sqrt() - 1.0);
        r[2] = x[2];
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        let temp = x[0] * x[0] + x[1] * x[1];
        let tmp1 = 2.0 * PI * temp;
        let tmp2 = temp.sqrt();
        j.copy_from_slice(&[
            100.0 * x[1] / tmp1,
            -100.0 * x[0] / tmp1,
            10.0,
            10.0 * x[0] / tmp2,
            10.0 * x[1] / tmp2,
            0.0,
            0.0,
            0.0,
            1.0,
        ]);
    }
}

/// Powell singular: `r = (x₁ + 10x₂, √5(x₃ − x₄), (x₂ − 2x₃)², √10(x₁ − x₄)²)`; zero
/// residual at 0, where the Jacobian is singular.
pub struct PowellSingular;

impl MghProblem for PowellSingular {
    fn name(&self) -> &str {
        "Powell singular"
    }
    fn m(&self) -> usize {
        4
    }
    fn n(&self) -> usize {
        4
    }
    fn start(&self) -> Vec<f64> {
        vec![3.0, -1.0, 0.0, 1.0]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        r[0] = x[0] + 10.0 * x[1];
        r[1] = 5f64.sqrt() * (x[2] - x[3]);
        r[2] = (x[1] - 2.0 * x[2]).powi(2);
        r[3] = 10f64.sqrt() * (x[0] - x[3]).powi(2);
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        let (s5, s10) = (5f64.sqrt(), 10f64.sqrt());
        let a = 2.0 * (x[1] - 2.0 * x[2]);
        let b = 2.0 * s10 * (x[0] - x[3]);
        j.copy_from_slice(&[
            1.0,
            10.0,
            0.0,
            0.0, //
            0.0,
            0.0,
            s5,
            -s5, //
            0.0,
            a,
            -2.0 * a,
            0.0, //
            b,
            0.0,
            0.0,
            -b,
        ]);
    }
}

/// Freudenstein and Roth: zero residual at (5, 4), a local minimum with `‖r‖² = 48.9842…`
/// at (11.41…, −0.8968…).
pub struct FreudensteinRoth;

impl MghProblem for FreudensteinRoth {
    fn name(&self) -> &str {
        "Freudenstein and Roth"
    }
    fn m(&self) -> usize {
        2
    }
    fn n(&self) -> usize {
        2
    }
    fn start(&self) -> Vec<f64> {
        vec![0.5, -2.0]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        r[0] = -13.0 + x[0] + ((5.0 - x[1]) * x[1] - 2.0) * x[1];
        r[1] = -29.0 + x[0] + ((1.0 + x[1]) * x[1] - 14.0) * x[1];
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        j.copy_from_slice(&[1.0, x[1] * (10.0 - 3.0 * x[1]) - 2.0, 1.0, x[1] * (2.0 + 3.0 * x[1]) - 14.0]);
    }
}

/// Box three-dimensional: `r_i = e^{−t_i x₁} − e^{−t_i x₂} − x₃(e^{−t_i} − e^{−i})`,
/// `t_i = i/10`; zero residual at (1, 10, 1) (and on other lines).
pub struct BoxThreeD {
    /// Residuals m ≥ 3.
    pub m: usize,
}

impl MghProblem for BoxThreeD {
    fn name(&self) -> &str {
        "Box three-dimensional"
    }
    fn m(&self) -> usize {
        self.m
    }
    fn n(&self) -> usize {
        3
    }
    fn start(&self) -> Vec<f64> {
        vec![0.0, 10.0, 20.0]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().enumerate() {
            let temp = (i + 1) as f64;
            let t = temp / 10.0;
            *ri = (-t * x[0]).exp() - (-t * x[1]).exp() + ((-temp).exp() - (-t).exp()) * x[2];
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        for i in 0..self.m {
            let temp = (i + 1) as f64;
            let t = temp / 10.0;
            j[3 * i] = -t * (-t * x[0]).exp();
            j[3 * i + 1] = t * (-t * x[1]).exp();
            j[3 * i + 2] = (-temp).exp() - (-t).exp();
        }
    }
}

/// Jennrich and Sampson: `r_i = 2 + 2i − e^{i x₁} − e^{i x₂}`; for m = 10 the minimum is
/// `‖r‖² = 124.362…` at x₁ = x₂ = 0.2578.
pub struct JennrichSampson {
    /// Residuals m ≥ 2.
    pub m: usize,
}

impl MghProblem for JennrichSampson {
    fn name(&self) -> &str {
        "Jennrich and Sampson"
    }
    fn m(&self) -> usize {
        self.m
    }
    fn n(&self) -> usize {
        2
    }
    fn start(&self) -> Vec<f64> {
        vec![0.3, 0.4]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().enumerate() {
            let t = (i + 1) as f64;
            *ri = 2.0 + 2.0 * t - (t * x[0]).exp() - (t * x[1]).exp();
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        for i in 0..self.m {
            let t = (i + 1) as f64;
            j[2 * i] = -t * (t * x[0]).exp();
            j[2 * i + 1] = -t * (t * x[1]).exp();
        }
    }
}

/// Brown and Dennis: `r_i = (x₁ + t_i x₂ − e^{t_i})² + (x₃ + x₄ sin t_i − cos t_i)²`,
/// `t_i = i/5`; for m = 20 the minimum is `‖r‖² = 85822.2…`.
pub struct BrownDennis {
    /// Residuals m ≥ 4.
    pub m: usize,
}

impl MghProblem for BrownDennis {
    fn name(&self) -> &str {
        "Brown and Dennis"
    }
    fn m(&self) -> usize {
        self.m
    }
    fn n(&self) -> usize {
        4
    }
    fn start(&self) -> Vec<f64> {
        vec![25.0, 5.0, -5.0, -1.0]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().enumerate() {
            let t = (i + 1) as f64 / 5.0;
            let a = x[0] + t * x[1] - t.exp();
            let b = x[2] + t.sin() * x[3] - t.cos();
            *ri = a * a + b * b;
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        for i in 0..self.m {
            let t = (i + 1) as f64 / 5.0;
            let a = x[0] + t * x[1] - t.exp();
            let b = x[2] + t.sin() * x[3] - t.cos();
            j[4 * i..4 * i + 4].copy_from_slice(&[2.0 * a, 2.0 * a * t, 2.0 * b, 2.0 * b * t.sin()]);
        }
    }
}
