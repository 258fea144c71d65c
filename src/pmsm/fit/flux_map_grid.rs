//! A flux map's points as a grid of currents, when they form one: the map's own value at a
//! grid current and its central differences there ([`super::flux_map_check`]).

/// The map's points as a grid `ψ[j][k]` at `i_d = d[j]`, `i_q = q[k]`, when they form one.
pub(super) struct Grid {
    pub d: Vec<f64>,
    pub q: Vec<f64>,
    pub psi: Vec<Vec<[f64; 2]>>,
}

impl Grid {
    /// The grid of the points, or `None` when they are not a full grid.
    pub(super) fn of(i: &[[f64; 2]], psi: &[[f64; 2]]) -> Option<Self> {
        let axis = |k: usize| {
            let mut v: Vec<f64> = i.iter().map(|p| p[k]).collect();
            v.sort_by(f64::total_cmp);
            v.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * (1.0 + b.abs()));
            v
        };
        let (d, q) = (axis(0), axis(1));
        if d.len() * q.len() != i.len() || d.len() < 2 || q.len() < 2 {
            return None;
        }
        let at = |v: &[f64], x: f64| v.iter().position(|a| (a - x).abs() <= 1e-9 * (1.0 + x.abs()));
        let mut grid = vec![vec![[f64::NAN; 2]; q.len()]; d.len()];
        for (p, s) in i.iter().zip(psi) {
            grid[at(&d, p[0])?][at(&q, p[1])?] = *s;
        }
        grid.iter().flatten().all(|s| s[0].is_finite()).then_some(Self { d, q, psi: grid })
    }

    /// The index of `x` on axis `v`, if it is a grid value.
    pub(super) fn index(v: &[f64], x: f64) -> Option<usize> {
        v.iter().position(|a| (a - x).abs() <= 1e-9 * (1.0 + x.abs()))
    }

    /// Central differences `[∂ψ_d/∂i_d, ∂ψ_q/∂i_q, ∂ψ_d/∂i_q]` at grid point `p` (one-sided
    /// at the grid's edges) of the flux `psi` at the grid's currents: the map's own, or a
    /// model's on the same stencil.
    pub(super) fn differences(
        &self,
        p: [f64; 2],
        psi: &dyn Fn([f64; 2]) -> Option<[f64; 2]>,
    ) -> Option<[f64; 3]> {
        let (j, k) = (Self::index(&self.d, p[0])?, Self::index(&self.q, p[1])?);
        let span = |n: usize, x: usize| (x.saturating_sub(1), (x + 1).min(n - 1));
        let ((j0, j1), (k0, k1)) = (span(self.d.len(), j), span(self.q.len(), k));
        let at = |a: usize, b: usize| psi([self.d[a], self.q[b]]);
        let dd = (at(j1, k)?[0] - at(j0, k)?[0]) / (self.d[j1] - self.d[j0]);
        let qq = (at(j, k1)?[1] - at(j, k0)?[1]) / (self.q[k1] - self.q[k0]);
        let dq = (at(j, k1)?[0] - at(j, k0)?[0]) / (self.q[k1] - self.q[k0]);
        Some([dd, qq, dq])
    }

    /// The map's flux at a grid current.
    pub(super) fn psi(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        Some(self.psi[Self::index(&self.d, p[0])?][Self::index(&self.q, p[1])?])
    }

    /// The grid value of axis `v` nearest `x`.
    pub(super) fn nearest(v: &[f64], x: f64) -> f64 {
        v.iter().copied().min_by(|a, b| (a - x).abs().total_cmp(&(b - x).abs())).unwrap_or(x)
    }
}
