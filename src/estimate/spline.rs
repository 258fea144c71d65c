//! A smooth surface `z(x, y)` fitted to scattered points by tensor-product cubic B-splines
//! on uniform knots, by linear least squares, with the number of knot intervals per axis
//! chosen by the held-out (leave-one-out) error and the covariance of the coefficients, so
//! that the surface's value and slopes at any point come with standard errors.
//!
//! The uniform cubic B-spline basis and its derivative (de Boor, *A Practical Guide to
//! Splines*, 1978, ch. IX; Dierckx, *Curve and Surface Fitting with Splines*, 1993, ch. 2
//! for tensor-product least squares); the leave-one-out residual of a linear smoother
//! `e_i/(1 − h_ii)` with `h_ii` the hat matrix's diagonal (Allen's PRESS, *Technometrics*
//! 16 (1974) 125–127; Hastie, Tibshirani & Friedman, *The Elements of Statistical
//! Learning*, 2nd ed., 2009, 7.10).

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// The knot intervals per axis tried by [`SplineSurface::fit_chosen`].
pub const SPLINE_INTERVALS: [usize; 11] = [1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 18];

/// A fitted tensor-product cubic B-spline surface on `[x0, x1] × [y0, y1]` (a regression
/// spline: least squares on a fixed uniform knot grid, no roughness penalty). Outside the
/// ranges the surface is held at its edge value (no extrapolation).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SplineSurface {
    /// The x range `[x0, x1]` \[unit of x\] and its knot intervals.
    pub x: ([f64; 2], usize),
    /// The y range `[y0, y1]` \[unit of y\] and its knot intervals.
    pub y: ([f64; 2], usize),
    /// Coefficients, `(m_x + 3) (m_y + 3)`, x-major.
    pub coefficients: Vec<f64>,
    /// Their covariance `σ̂² (XᵀX)⁻¹` (white residuals), row-major, n × n.
    pub covariance: Vec<f64>,
    /// RMS residual over the points \[unit of z\].
    pub rms: f64,
    /// RMS leave-one-out residual over the points \[unit of z\].
    pub held_out_rms: f64,
}

/// The four uniform cubic B-splines that are non-zero at `v` on `[lo, hi]` cut into `m`
/// intervals: the first index and the values and the derivatives (per unit of `v`).
fn basis(v: f64, [lo, hi]: [f64; 2], m: usize) -> (usize, [f64; 4], [f64; 4]) {
    let m = m.max(1);
    let h = (hi - lo) / m as f64;
    let s = ((v - lo) / h).clamp(0.0, m as f64);
    let j = (s.floor() as usize).min(m - 1);
    let t = s - j as f64;
    let u = 1.0 - t;
    let b = [
        u * u * u / 6.0,
        (3.0 * t * t * t - 6.0 * t * t + 4.0) / 6.0,
        (-3.0 * t * t * t + 3.0 * t * t + 3.0 * t + 1.0) / 6.0,
        t * t * t / 6.0,
    ];
    let d = [-u * u / 2.0, (3.0 * t * t - 4.0 * t) / 2.0, (-3.0 * t * t + 2.0 * t + 1.0) / 2.0, t * t / 2.0]
        .map(|x| x / h);
    (j, b, d)
}

impl SplineSurface {
    /// Coefficients in the model.
    fn size(&self) -> usize {
        (self.x.1 + 3) * (self.y.1 + 3)
    }

    /// The row of the design at `(x, y)`: the gradient of the value (`dx`, `dy` 0) or of
    /// its x or y slope with respect to the coefficients, as (index, weight) pairs.
    fn row(&self, p: [f64; 2], dx: bool, dy: bool) -> Vec<(usize, f64)> {
        row(p, self.x, self.y, dx, dy)
    }

    /// `(value, standard error)` of `z` (`dx = dy = false`), `∂z/∂x` or `∂z/∂y` at `p`;
    /// NaN for a surface whose coefficients do not match its knots (a bad deserialised one).
    fn with_error(&self, p: [f64; 2], dx: bool, dy: bool) -> (f64, f64) {
        let n = self.size();
        if self.coefficients.len() != n || self.covariance.len() != n * n {
            return (f64::NAN, f64::NAN);
        }
        let r = self.row(p, dx, dy);
        let v = r.iter().map(|&(i, w)| w * self.coefficients[i]).sum();
        let var: f64 = r
            .iter()
            .flat_map(|&(i, a)| r.iter().map(move |&(j, b)| a * b * self.covariance[i * n + j]))
            .sum();
        (v, var.max(0.0).sqrt())
    }

    /// The surface's value at `p = (x, y)` and its standard error \[unit of z\].
    pub fn value(&self, p: [f64; 2]) -> (f64, f64) {
        self.with_error(p, false, false)
    }

    /// `∂z/∂x` at `p` and its standard error \[unit of z per unit of x\].
    pub fn slope_x(&self, p: [f64; 2]) -> (f64, f64) {
        self.with_error(p, true, false)
    }

    /// `∂z/∂y` at `p` and its standard error \[unit of z per unit of y\].
    pub fn slope_y(&self, p: [f64; 2]) -> (f64, f64) {
        self.with_error(p, false, true)
    }

    /// The least-squares surface through `points` (`[x, y]`, n) and values `z` (n) with
    /// `m_x`, `m_y` knot intervals on the points' ranges.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (`z`) when `z` and `points` differ in length or hold a
    /// non-finite number; [`Error::Numerical`] when the normal matrix is singular (a knot
    /// interval without points, fewer points than coefficients, a range of zero width).
    pub fn fit(points: &[[f64; 2]], z: &[f64], m_x: usize, m_y: usize) -> Result<Self> {
        if z.len() != points.len() || z.iter().chain(points.iter().flatten()).any(|v| !v.is_finite()) {
            return Err(Error::InvalidOption {
                option: "z".into(),
                reason: format!(
                    "{} values for {} points, or a value that is not finite: one finite value per point",
                    z.len(),
                    points.len()
                ),
            });
        }
        let range = |k: usize| {
            points.iter().fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], p| [lo.min(p[k]), hi.max(p[k])])
        };
        let (rx, ry) = (range(0), range(1));
        let singular = |why: &str| Error::Numerical { context: "spline surface".into(), reason: why.into() };
        if !(rx[1] > rx[0] && ry[1] > ry[0]) || m_x == 0 || m_y == 0 {
            return Err(singular("the points span no area, or an axis has no knot interval"));
        }
        let n = (m_x + 3) * (m_y + 3);
        if points.len() <= n {
            return Err(singular("fewer points than coefficients"));
        }
        let rows: Vec<Vec<(usize, f64)>> =
            points.iter().map(|&p| row(p, (rx, m_x), (ry, m_y), false, false)).collect();
        let mut a = DMatrix::<f64>::zeros(n, n);
        let mut b = DVector::<f64>::zeros(n);
        for (r, &zk) in rows.iter().zip(z) {
            for &(i, wi) in r {
                b[i] += wi * zk;
                for &(j, wj) in r {
                    a[(i, j)] += wi * wj;
                }
            }
        }
        let chol = a
            .cholesky()
            .ok_or_else(|| singular("the normal matrix is singular (a knot interval without points)"))?;
        let c = chol.solve(&b);
        let inv = chol.inverse();
        let (mut sse, mut press) = (0.0, 0.0);
        for (r, &zk) in rows.iter().zip(z) {
            let e = zk - r.iter().map(|&(i, w)| w * c[i]).sum::<f64>();
            let h: f64 = r
                .iter()
                .flat_map(|&(i, a)| r.iter().map(move |&(j, b)| (i, j, a * b)))
                .map(|(i, j, ab)| ab * inv[(i, j)])
                .sum();
            sse += e * e;
            press += (e / (1.0 - h).max(1e-12)).powi(2);
        }
        let m = points.len() as f64;
        let sigma2 = sse / (m - n as f64);
        let covariance = (inv * sigma2).transpose().as_slice().to_vec();
        Ok(Self {
            x: (rx, m_x),
            y: (ry, m_y),
            coefficients: c.as_slice().to_vec(),
            covariance,
            rms: (sse / m).sqrt(),
            held_out_rms: (press / m).sqrt(),
        })
    }

    /// The surface of [`fit`](Self::fit) whose knot intervals (each axis from
    /// [`SPLINE_INTERVALS`]) give the least leave-one-out error.
    ///
    /// # Errors
    /// [`Error::Numerical`] when no choice can be fitted.
    pub fn fit_chosen(points: &[[f64; 2]], z: &[f64]) -> Result<Self> {
        let mut best: Option<Self> = None;
        for m_x in SPLINE_INTERVALS {
            for m_y in SPLINE_INTERVALS {
                let Ok(s) = Self::fit(points, z, m_x, m_y) else { continue };
                if s.held_out_rms.is_finite() && best.as_ref().is_none_or(|b| s.held_out_rms < b.held_out_rms)
                {
                    best = Some(s);
                }
            }
        }
        best.ok_or_else(|| Error::Numerical {
            context: "spline surface".into(),
            reason: "no knot intervals fit the points (too few points, or all on a line)".into(),
        })
    }
}

impl SplineSurface {
    /// The rms error over `points` of surfaces with this one's knot intervals fitted without
    /// each fold (`fold(k)` in `0..folds` the fold of point k) and evaluated on it \[unit of
    /// z\]; `None` when a fold's fit fails. The same split as another model's
    /// cross-validation makes the two comparable (leave-one-out favours the model it is
    /// computed for).
    pub fn cross_validated(
        &self,
        points: &[[f64; 2]],
        z: &[f64],
        folds: usize,
        fold: &dyn Fn(usize) -> usize,
    ) -> Option<f64> {
        let (mut sse, mut n) = (0.0, 0usize);
        for f in 0..folds {
            let (train, test): (Vec<usize>, Vec<usize>) = (0..points.len()).partition(|&k| fold(k) != f);
            let pick = |idx: &[usize]| -> (Vec<[f64; 2]>, Vec<f64>) {
                idx.iter().map(|&k| (points[k], z[k])).unzip()
            };
            let (p, v) = pick(&train);
            let s = Self::fit(&p, &v, self.x.1, self.y.1).ok()?;
            for k in test {
                sse += (s.value(points[k]).0 - z[k]).powi(2);
                n += 1;
            }
        }
        (n > 0).then(|| (sse / n as f64).sqrt())
    }
}

/// The design row at `p` for ranges and intervals `x`, `y` (the value, or its x or y slope).
fn row(p: [f64; 2], x: ([f64; 2], usize), y: ([f64; 2], usize), dx: bool, dy: bool) -> Vec<(usize, f64)> {
    let (jx, bx, ddx) = basis(p[0], x.0, x.1);
    let (jy, by, ddy) = basis(p[1], y.0, y.1);
    let (wx, wy) = (if dx { ddx } else { bx }, if dy { ddy } else { by });
    let ny = y.1 + 3;
    let mut out = Vec::with_capacity(16);
    for (a, u) in wx.iter().enumerate() {
        for (b, v) in wy.iter().enumerate() {
            out.push(((jx + a) * ny + jy + b, u * v));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cubic polynomial surface is in the spline space: fitted exactly, slopes exact, and
    /// the leave-one-out choice does not overfit noise much beyond it.
    #[test]
    fn a_cubic_surface_is_reproduced_with_its_slopes() {
        let f = |x: f64, y: f64| 1.0 + 0.5 * x - 0.2 * y + 0.1 * x * y + 0.03 * x * x * x - 0.02 * y * y;
        let mut pts = Vec::new();
        let mut z = Vec::new();
        for i in -10..=10 {
            for j in -8..=8 {
                let (x, y) = (f64::from(i), f64::from(j) * 1.5);
                pts.push([x, y]);
                z.push(f(x, y));
            }
        }
        let s = SplineSurface::fit(&pts, &z, 4, 3).unwrap();
        assert!(s.rms < 1e-10, "{}", s.rms);
        let (v, _) = s.value([0.3, -2.0]);
        assert!((v - f(0.3, -2.0)).abs() < 1e-9);
        let (gx, _) = s.slope_x([0.3, -2.0]);
        assert!((gx - (0.5 + 0.1 * -2.0 + 0.09 * 0.09)).abs() < 1e-8, "{gx}");
        let (gy, _) = s.slope_y([0.3, -2.0]);
        assert!((gy - (-0.2 + 0.1 * 0.3 + 0.08)).abs() < 1e-8, "{gy}");
        let chosen = SplineSurface::fit_chosen(&pts, &z).unwrap();
        assert!(chosen.held_out_rms < 1e-8);
    }

    /// With noise, the value's interval covers the truth about as often as it says.
    #[test]
    fn the_value_interval_covers_under_noise() {
        let f = |x: f64, y: f64| (0.3 * x).sin() + 0.1 * y;
        let mut rng = crate::estimate::test_rng::Xorshift::new(0x2545_f491_4f6c_dd1d);
        let mut normal = || {
            let mut u = || rng.uniform();
            (-2.0 * u().max(1e-300).ln()).sqrt() * (std::f64::consts::TAU * u()).cos()
        };
        let mut covered = 0;
        let trials = 200;
        for _ in 0..trials {
            let mut pts = Vec::new();
            let mut z = Vec::new();
            for i in -10..=10 {
                for j in -5..=5 {
                    let (x, y) = (f64::from(i), f64::from(j));
                    pts.push([x, y]);
                    z.push(f(x, y) + 0.05 * normal());
                }
            }
            let s = SplineSurface::fit(&pts, &z, 5, 2).unwrap();
            let (v, se) = s.value([0.0, 0.0]);
            if (v - f(0.0, 0.0)).abs() <= 1.96 * se {
                covered += 1;
            }
        }
        let rate = f64::from(covered) / f64::from(trials);
        assert!((0.90..=0.99).contains(&rate), "coverage {rate}");
    }
}
