//! MGH problems with a variable number of variables: Watson (MGH 20), Chebyquad (35),
//! Brown almost-linear (27); MINPACK numbers 11, 15, 16.

use super::MghProblem;

/// Watson: for `t_i = i/29`, i = 1…29,
/// `r_i = Σ_{j=2}^{n} (j − 1) x_j t_i^{j−2} − (Σ_{j=1}^{n} x_j t_i^{j−1})² − 1`,
/// `r₃₀ = x₁`, `r₃₁ = x₂ − x₁² − 1`; m = 31. Minimum `‖r‖²` = 2.28767…e-3 (n = 6),
/// 1.39976…e-6 (n = 9), 4.72238…e-10 (n = 12).
pub struct Watson {
    /// Variables n (2 ≤ n ≤ 31).
    pub n: usize,
}

impl MghProblem for Watson {
    fn name(&self) -> &str {
        "Watson"
    }
    fn m(&self) -> usize {
        31
    }
    fn n(&self) -> usize {
        self.n
    }
    fn start(&self) -> Vec<f64> {
        vec![0.0; self.n]
    }
    /// MINPACK's driver starts Watson at `x_j = factor` for factor ≠ 1 (x₀ = 0).
    fn start_at(&self, factor: f64) -> Vec<f64> {
        if factor == 1.0 { self.start() } else { vec![factor; self.n] }
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        for (i, ri) in r.iter_mut().take(29).enumerate() {
            let div = (i + 1) as f64 / 29.0;
            let (mut s1, mut dx) = (0.0, 1.0);
            for (j, xj) in x.iter().enumerate().skip(1) {
                s1 += j as f64 * dx * xj;
                dx *= div;
            }
            let (mut s2, mut dx) = (0.0, 1.0);
            for xj in x {
                s2 += dx * xj;
                dx *= div;
            }
            *ri = s1 - s2 * s2 - 1.0;
        }
        r[29] = x[0];
        r[30] = x[1] - x[0] * x[0] - 1.0;
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        let n = self.n;
        for i in 0..29 {
            let div = (i + 1) as f64 / 29.0;
            let (mut s2, mut dx) = (0.0, 1.0);
            for xj in x {
                s2 += dx * xj;
                dx *= div;
            }
            let temp = 2.0 * div * s2;
            let mut dx = 1.0 / div;
            for k in 0..n {
                j[i * n + k] = dx * (k as f64 - temp);
                dx *= div;
            }
        }
        j[29 * n..].fill(0.0);
        j[29 * n] = 1.0;
        j[30 * n] = -2.0 * x[0];
        j[30 * n + 1] = 1.0;
    }
}

/// Chebyquad: `r_i = (1/n) Σ_j T_i(2x_j − 1) + [i even] 1/(i² − 1)`, `T_i` the shifted
/// Chebyshev polynomials, i = 1…m; zero residual for n = 1…7 and 9, minimum `‖r‖²` =
/// 3.51687…e-3 (n = 8), 6.50395…e-3 (n = 10).
pub struct Chebyquad {
    /// Variables n.
    pub n: usize,
    /// Residuals m ≥ n.
    pub m: usize,
}

impl MghProblem for Chebyquad {
    fn name(&self) -> &str {
        "Chebyquad"
    }
    fn m(&self) -> usize {
        self.m
    }
    fn n(&self) -> usize {
        self.n
    }
    fn start(&self) -> Vec<f64> {
        let h = 1.0 / (self.n + 1) as f64;
        (1..=self.n).map(|j| j as f64 * h).collect()
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        r.fill(0.0);
        for xj in x {
            // Three-term recurrence T_{i+1} = 2y T_i − T_{i−1}, y = 2x − 1.
            let (mut tmp1, mut tmp2) = (1.0, 2.0 * xj - 1.0);
            let temp = 2.0 * tmp2;
            for ri in r.iter_mut() {
                *ri += tmp2;
                let ti = temp * tmp2 - tmp1;
                tmp1 = tmp2;
                tmp2 = ti;
            }
        }
        let dx = 1.0 / self.n as f64;
        for (i, ri) in r.iter_mut().enumerate() {
            *ri *= dx;
            let k = (i + 1) as f64;
            if (i + 1) % 2 == 0 {
                *ri += 1.0 / (k * k - 1.0);
            }
        }
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        let (n, dx) = (self.n, 1.0 / self.n as f64);
        for (k, xk) in x.iter().enumerate() {
            // d/dx T_i(2x − 1) by differentiating the recurrence.
            let (mut tmp1, mut tmp2) = (1.0, 2.0 * xk - 1.0);
            let temp = 2.0 * tmp2;
            let (mut tmp3, mut tmp4) = (0.0, 2.0);
            for i in 0..self.m {
                j[i * n + k] = dx * tmp4;
                let ti = 4.0 * tmp2 + temp * tmp4 - tmp3;
                tmp3 = tmp4;
                tmp4 = ti;
                let ti = temp * tmp2 - tmp1;
                tmp1 = tmp2;
                tmp2 = ti;
            }
        }
    }
}

/// Brown almost-linear: `r_i = x_i + Σ_j x_j − (n + 1)` (i < n), `r_n = Π_j x_j − 1`;
/// m = n, zero residual at x = 1 (and elsewhere).
pub struct BrownAlmostLinear {
    /// Variables n = m.
    pub n: usize,
}

impl MghProblem for BrownAlmostLinear {
    fn name(&self) -> &str {
        "Brown almost-linear"
    }
    fn m(&self) -> usize {
        self.n
    }
    fn n(&self) -> usize {
        self.n
    }
    fn start(&self) -> Vec<f64> {
        vec![0.5; self.n]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        let sum = x.iter().sum::<f64>() - (self.n + 1) as f64;
        let prod: f64 = x.iter().product();
        for (ri, xi) in r.iter_mut().zip(x) {
            *ri = xi + sum;
        }
        r[self.n - 1] = prod - 1.0;
    }
    fn jacobian(&self, x: &[f64], j: &mut [f64]) {
        let n = self.n;
        for i in 0..n - 1 {
            for k in 0..n {
                j[i * n + k] = if i == k { 2.0 } else { 1.0 };
            }
        }
        for k in 0..n {
            // Π_{l≠k} x_l, without dividing by a zero x_k.
            j[(n - 1) * n + k] = x.iter().enumerate().filter(|&(l, _)| l != k).map(|(_, xl)| xl).product();
        }
    }
}
