//! MGH curve fits to tabulated data: Bard (MGH 8), Kowalik and Osborne (15), Meyer (10),
//! Osborne 1 (17), Osborne 2 (19); MINPACK numbers 8, 9, 10, 17, 18. Data from `ssqfcn.f`.

use super::MghProblem;

const BARD_Y: [f64; 15] =
    [0.14, 0.18, 0.22, 0.25, 0.29, 0.32, 0.35, 0.39, 0.37, 0.58, 0.73, 0.96, 1.34, 2.10, 4.39];
const KOWALIK_V: [f64; 11] = [4.0, 2.0, 1.0, 0.5, 0.25, 0.167, 0.125, 0.1, 0.0833, 0.0714, 0.0625];
const KOWALIK_Y: [f64; 11] =
    [0.1957, 0.1947, 0.1735, 0.16, 0.0844, 0.0627, 0.0456, 0.0342, 0.0323, 0.0235, 0.0246];
const MEYER_Y: [f64; 16] = [
    3.478e4, 2.861e4, 2.365e4, 1.963e4, 1.637e4, 1.372e4, 1.154e4, 9.744e3, 8.261e3, 7.03e3, 6.005e3,
    5.147e3, 4.427e3, 3.82e3, 3.307e3, 2.872e3,
];
const OSBORNE1_Y: [f64; 33] = [
    0.844, 0.908, 0.932, 0.936, 0.925, 0.908, 0.881, 0.85, 0.818, 0.784, 0.751, 0.718, 0.685, 0.658, 0.628,
    0.603, 0.58, 0.558, 0.538, 0.522, 0.506, 0.49, 0.478, 0.467, 0.457, 0.448, 0.438, 0.431, 0.424, 0.42,
    0.414, 0.411, 0.406,
];
const OSBORNE2_Y: [f64; 65] = [
    1.366, 1.191, 1.112, 1.013, 0.991, 0.885, 0.831, 0.847, 0.786, 0.725, 0.746, 0.679, 0.608, 0.655, 0.616,
    0.606, 0.602, 0.626, 0.651, 0.724, 0.649, 0.649, 0.694, 0.644, 0.624, 0.661, 0.612, 0.558, 0.533, 0.495,
    0.5, 0.423, 0.395, 0.375, 0.372, 0.391, 0.396, 0.405, 0.428, 0.429, 0.523, 0.562, 0.607, 0.653, 0.672,
    0.708, 0.633, 0.668, 0.645, 0.632, 0.591, 0.559, 0.597, 0.625, 0.739, 0.71, 0.729, 0.72, 0.636, 0.581,
    0.428, 0.292, 0.162, 0.098, 0.054,
];

/// Bard: `r_i = y_i − (x₁ + u_i/(v_i x₂ + w_i x₃))`, `u_i = i`, `v_i = 16 − i`,
/// `w_i = min(u_i, v_i)`; minimum `‖r‖² = 8.21487…e-3`.
pub struct Bard;

impl Bard {
    fn uvw(i: usize) -> (f64, f64, f64) {
        let (u, v) = ((i + 1) as f64, (15 - i) as f64);
        (u, v, if i > 7 { v } else { u })
    }
}

impl MghProblem for Bard {
    fn name(&self) -> &str {
        "Bard"
    }
    fn m(&self) -> usize {
        15
    }
    fn n(&self) -> usize {
        3
    }
    fn start(&self) -> Vec<f64> {
        vec![1.0, 1.0, 1.0]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().enumerate() {
            let (u, v, w) = Self::uvw(i);
            *ri = BARD_Y[i] - (x[0] + u / (x[1] * v + x[2] * w));
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        for i in 0..15 {
            let (u, v, w) = Self::uvw(i);
            let d = (x[1] * v + x[2] * w).powi(2);
            j[3 * i..3 * i + 3].copy_from_slice(&[-1.0, u * v / d, u * w / d]);
        }
    }
}

/// Kowalik and Osborne: `r_i = y_i − x₁(v_i² + v_i x₂)/(v_i² + v_i x₃ + x₄)`; minimum
/// `‖r‖² = 3.07505…e-4`.
pub struct KowalikOsborne;

impl MghProblem for KowalikOsborne {
    fn name(&self) -> &str {
        "Kowalik and Osborne"
    }
    fn m(&self) -> usize {
        11
    }
    fn n(&self) -> usize {
        4
    }
    fn start(&self) -> Vec<f64> {
        vec![0.25, 0.39, 0.415, 0.39]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().enumerate() {
            let v = KOWALIK_V[i];
            *ri = KOWALIK_Y[i] - x[0] * (v * (v + x[1])) / (v * (v + x[2]) + x[3]);
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        for i in 0..11 {
            let v = KOWALIK_V[i];
            let (tmp1, tmp2) = (v * (v + x[1]), v * (v + x[2]) + x[3]);
            let (j1, j2) = (-tmp1 / tmp2, -v * x[0] / tmp2);
            j[4 * i..4 * i + 4].copy_from_slice(&[j1, j2, j1 * j2, j1 * j2 / v]);
        }
    }
}

/// Meyer: `r_i = x₁ exp(x₂/(t_i + x₃)) − y_i`, `t_i = 45 + 5i`; minimum `‖r‖² = 87.9458…`.
pub struct Meyer;

impl MghProblem for Meyer {
    fn name(&self) -> &str {
        "Meyer"
    }
    fn m(&self) -> usize {
        16
    }
    fn n(&self) -> usize {
        3
    }
    fn start(&self) -> Vec<f64> {
        vec![0.02, 4000.0, 250.0]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().enumerate() {
            let temp = 5.0 * (i + 1) as f64 + 45.0 + x[2];
            *ri = x[0] * (x[1] / temp).exp() - MEYER_Y[i];
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        for i in 0..16 {
            let temp = 5.0 * (i + 1) as f64 + 45.0 + x[2];
            let tmp1 = x[1] / temp;
            let e = tmp1.exp();
            let j2 = x[0] * e / temp;
            j[3 * i..3 * i + 3].copy_from_slice(&[e, j2, -tmp1 * j2]);
        }
    }
}

/// Osborne 1: `r_i = y_i − (x₁ + x₂ e^{−t_i x₄} + x₃ e^{−t_i x₅})`, `t_i = 10(i − 1)`;
/// minimum `‖r‖² = 5.46489…e-5`.
pub struct Osborne1;

impl MghProblem for Osborne1 {
    fn name(&self) -> &str {
        "Osborne 1"
    }
    fn m(&self) -> usize {
        33
    }
    fn n(&self) -> usize {
        5
    }
    fn start(&self) -> Vec<f64> {
        vec![0.5, 1.5, -1.0, 0.01, 0.02]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().enumerate() {
            let t = 10.0 * i as f64;
            *ri = OSBORNE1_Y[i] - (x[0] + x[1] * (-x[3] * t).exp() + x[2] * (-x[4] * t).exp());
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        for i in 0..33 {
            let t = 10.0 * i as f64;
            let (e4, e5) = ((-x[3] * t).exp(), (-x[4] * t).exp());
            j[5 * i..5 * i + 5].copy_from_slice(&[-1.0, -e4, -e5, t * x[1] * e4, t * x[2] * e5]);
        }
    }
}

/// Osborne 2: `r_i = y_i − (x₁ e^{−t_i x₅} + Σ_{k=2}^{4} x_k e^{−x_{k+4}(t_i − x_{k+7})²})`,
/// `t_i = (i − 1)/10`; minimum `‖r‖² = 4.01377…e-2`.
pub struct Osborne2;

impl MghProblem for Osborne2 {
    fn name(&self) -> &str {
        "Osborne 2"
    }
    fn m(&self) -> usize {
        65
    }
    fn n(&self) -> usize {
        11
    }
    fn start(&self) -> Vec<f64> {
        vec![1.3, 0.65, 0.65, 0.7, 0.6, 3.0, 5.0, 7.0, 2.0, 4.5, 5.5]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().enumerate() {
            let t = i as f64 / 10.0;
            let e1 = (-x[4] * t).exp();
            let bump = |k: usize| x[k] * (-x[k + 4] * (t - x[k + 7]).powi(2)).exp();
            *ri = OSBORNE2_Y[i] - (x[0] * e1 + bump(1) + bump(2) + bump(3));
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        for i in 0..65 {
            let t = i as f64 / 10.0;
            let row = &mut j[11 * i..11 * i + 11];
            let e1 = (-x[4] * t).exp();
            row[0] = -e1;
            row[4] = t * x[0] * e1;
            for k in 1..4 {
                let d = t - x[k + 7];
                let e = (-x[k + 4] * d * d).exp();
                row[k] = -e;
                row[k + 4] = x[k] * d * d * e;
                row[k + 7] = -2.0 * x[k] * x[k + 4] * d * e;
            }
        }
    }
}
