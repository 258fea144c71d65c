//! MGH problems 32–34 (MINPACK 1–3): linear functions, full rank and rank 1, m ≥ n.

use super::MghProblem;

/// Linear function, full rank: `r_i = x_i − (2/m) Σ_j x_j − 1` (i ≤ n), `−(2/m) Σ_j x_j − 1`
/// (i > n). Minimum `‖r‖² = m − n` at `x = −1`.
pub struct LinearFullRank {
    /// Variables n.
    pub n: usize,
    /// Residuals m ≥ n.
    pub m: usize,
}

impl MghProblem for LinearFullRank {
    fn name(&self) -> &str {
        "Linear function - full rank"
    }
    fn m(&self) -> usize {
        self.m
    }
    fn n(&self) -> usize {
        self.n
    }
    fn start(&self) -> Vec<f64> {
        vec![1.0; self.n]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        let temp = 2.0 * x.iter().sum::<f64>() / self.m as f64 + 1.0;
        for (i, ri) in r.iter_mut().enumerate() {
            *ri = -temp;
            if i < self.n {
                *ri += x[i];
            }
        }
    }
    fn jacobian(&self, _x: &[f64], j: &mut [f64]) {
        let temp = 2.0 / self.m as f64;
        for i in 0..self.m {
            for k in 0..self.n {
                j[i * self.n + k] = if i == k { 1.0 - temp } else { -temp };
            }
        }
    }
}

/// Linear function, rank 1: `r_i = i Σ_j j x_j − 1` (1-based i, j). Minimum
/// `‖r‖² = m(m − 1)/(2(2m + 1))` on the hyperplane `Σ_j j x_j = 3/(2m + 1)`.
pub struct LinearRank1 {
    /// Variables n.
    pub n: usize,
    /// Residuals m ≥ n.
    pub m: usize,
}

impl MghProblem for LinearRank1 {
    fn name(&self) -> &str {
        "Linear function - rank 1"
    }
    fn m(&self) -> usize {
        self.m
    }
    fn n(&self) -> usize {
        self.n
    }
    fn start(&self) -> Vec<f64> {
        vec![1.0; self.n]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        let sum: f64 = x.iter().enumerate().map(|(j, xj)| (j + 1) as f64 * xj).sum();
        for (i, ri) in r.iter_mut().enumerate() {
            *ri = (i + 1) as f64 * sum - 1.0;
        }
    }
    fn jacobian(&self, _x: &[f64], j: &mut [f64]) {
        for i in 0..self.m {
            for k in 0..self.n {
                j[i * self.n + k] = ((i + 1) * (k + 1)) as f64;
            }
        }
    }
}

/// Linear function, rank 1 with zero columns and rows: `r_i = (i − 1) Σ_{j=2}^{n−1} j x_j − 1`
/// (1-based, i < m), `r_m = −1`. Minimum `‖r‖² = (m² + 3m − 6)/(2(2m − 3))`.
pub struct LinearRank1ZeroColumns {
    /// Variables n.
    pub n: usize,
    /// Residuals m ≥ n.
    pub m: usize,
}

impl MghProblem for LinearRank1ZeroColumns {
    fn name(&self) -> &str {
        "Linear function - rank 1 with zero columns and rows"
    }
    fn m(&self) -> usize {
        self.m
    }
    fn n(&self) -> usize {
        self.n
    }
    fn start(&self) -> Vec<f64> {
        vec![1.0; self.n]
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        let sum: f64 = (1..self.n.saturating_sub(1)).map(|j| (j + 1) as f64 * x[j]).sum();
        for (i, ri) in r.iter_mut().enumerate() {
            *ri = i as f64 * sum - 1.0;
        }
        r[self.m - 1] = -1.0;
    }
    fn jacobian(&self, _x: &[f64], j: &mut [f64]) {
        for i in 0..self.m {
            for k in 0..self.n {
                let inner = (1..self.n - 1).contains(&k) && (1..self.m - 1).contains(&i);
                j[i * self.n + k] = if inner { (i * (k + 1)) as f64 } else { 0.0 };
            }
        }
    }
}
