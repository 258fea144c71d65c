//! The rows of the linear regression on the voltage equations (the documentation of
//! [`crate::pmsm::linear`]), streamed interval by interval without forming the row matrix.

use crate::error::Result;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::SQRT_2_3;
use crate::pmsm::model::kind::MotorKind;

/// The regression rows of one experiment, interval by interval, without storing them:
/// interval `k = 0..N−2` gives a d row and a q row (thesis 5.2.1; [`least_squares`](crate::pmsm::least_squares)) and the
/// voltages `(u_d[k], u_q[k])` they explain.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Regression<'a> {
    i_d: &'a [f64],
    i_q: &'a [f64],
    w_m: &'a [f64],
    u_d: &'a [f64],
    u_q: &'a [f64],
    h: f64,
    np: f64,
    kind: MotorKind,
}

/// Regressor columns of the largest model (IPM).
pub(crate) const MAX_COLS: usize = 4;

/// Pushes one interval's d and q rows (first `cols` regressors of `d`, `q`, targets `u`)
/// into `ls`, with the dead-time direction `dir` (per unit `v_dt`, enters as `−dir`) as one
/// more regressor column.
pub(crate) fn push_with_dead_time(
    ls: &mut crate::estimate::linear::StreamedLeastSquares,
    d: &[f64],
    q: &[f64],
    u: [f64; 2],
    cols: usize,
    dir: crate::pmsm::model::interval::C64,
) {
    let (mut drow, mut qrow) = ([0.0; MAX_COLS + 1], [0.0; MAX_COLS + 1]);
    drow[..cols].copy_from_slice(&d[..cols]);
    qrow[..cols].copy_from_slice(&q[..cols]);
    (drow[cols], qrow[cols]) = (-dir.re, -dir.im);
    ls.push(&drow[..=cols], u[0], 1.0);
    ls.push(&qrow[..=cols], u[1], 1.0);
}

impl<'a> Regression<'a> {
    /// The regression of `e` on the voltage `(u_d, u_q)` (period means \[V\], length N each:
    /// the terminal voltage or an applied one).
    pub(crate) fn new(e: &DqView<'a>, u_d: &'a [f64], u_q: &'a [f64], n_p: u32, kind: MotorKind) -> Self {
        Self { i_d: e.i_d(), i_q: e.i_q(), w_m: e.w_m(), u_d, u_q, h: e.h(), np: f64::from(n_p), kind }
    }

    /// Number of intervals N − 1 (each gives a d and a q row).
    pub(crate) fn intervals(&self) -> usize {
        self.i_d.len().min(self.u_d.len()).min(self.u_q.len()).saturating_sub(1)
    }

    /// Regressor columns n_θ of the kind.
    pub(crate) fn cols(&self) -> usize {
        match self.kind {
            MotorKind::Spm => 3,
            MotorKind::Ipm => 4,
        }
    }

    /// The d row, the q row (the first [`cols`](Self::cols) entries) and `(u_d[k], u_q[k])`
    /// of interval k `< intervals()`.
    #[inline]
    pub(crate) fn rows(&self, k: usize) -> ([f64; MAX_COLS], [f64; MAX_COLS], [f64; 2]) {
        let (d, q) = self.pair(
            [self.i_d[k], self.i_d[k + 1]],
            [self.i_q[k], self.i_q[k + 1]],
            [self.w_m[k], self.w_m[k + 1]],
        );
        (d, q, [self.u_d[k], self.u_q[k]])
    }

    /// [`rows`](Self::rows) of every interval in order, as `f(k, d row, q row, (u_d, u_q))`.
    #[inline]
    pub(crate) fn for_each(&self, mut f: impl FnMut(usize, &[f64; MAX_COLS], &[f64; MAX_COLS], [f64; 2])) {
        let currents = self.i_d.windows(2).zip(self.i_q.windows(2));
        let voltages = self.u_d.iter().zip(self.u_q);
        for (k, (((id, iq), wm), (ud, uq))) in currents.zip(self.w_m.windows(2)).zip(voltages).enumerate() {
            let (d, q) = self.pair([id[0], id[1]], [iq[0], iq[1]], [wm[0], wm[1]]);
            f(k, &d, &q, [*ud, *uq]);
        }
    }

    /// The d and q rows from the currents and speeds at both ends of an interval.
    #[inline]
    fn pair(&self, id: [f64; 2], iq: [f64; 2], wm: [f64; 2]) -> ([f64; MAX_COLS], [f64; MAX_COLS]) {
        let h = self.h;
        let (idm, iqm) = (0.5 * (id[0] + id[1]), 0.5 * (iq[0] + iq[1]));
        let (did, diq) = ((id[1] - id[0]) / h, (iq[1] - iq[0]) / h);
        let w_m = 0.5 * (wm[0] + wm[1]);
        let w_e = self.np * w_m;
        match self.kind {
            MotorKind::Spm => ([idm, did - w_e * iqm, 0.0, 0.0], [iqm, diq + w_e * idm, SQRT_2_3 * w_m, 0.0]),
            MotorKind::Ipm => ([idm, did, -w_e * iqm, 0.0], [iqm, w_e * idm, diq, SQRT_2_3 * w_m]),
        }
    }
}

/// Regressor matrix Φ (rows × n_θ, row-major, rows = 2(N − 1)) and voltages y (length
/// rows) of one experiment, unfiltered and unweighted. The fits themselves stream these rows
/// and never form Φ; this is for inspection and tests.
///
/// Rows alternate d, q for every interval `k = 0..N−2` (thesis 5.2.1; [`least_squares`](crate::pmsm::least_squares)).
///
/// # Errors
/// [`crate::Error::MissingChannel`] (`ud`) for a log without the terminal voltage (regress on
/// [`crate::pmsm::applied_experiment`]'s voltage instead).
pub fn regressors(e: &DqView<'_>, n_p: u32, kind: MotorKind) -> Result<(Vec<f64>, Vec<f64>)> {
    let (u_d, u_q) = e.terminal_voltage()?;
    let reg = Regression::new(e, u_d, u_q, n_p, kind);
    let (n, cols) = (reg.intervals(), reg.cols());
    let mut phi = Vec::with_capacity(2 * n * cols);
    let mut y = Vec::with_capacity(2 * n);
    reg.for_each(|_, d, q, u| {
        phi.extend_from_slice(&d[..cols]);
        phi.extend_from_slice(&q[..cols]);
        y.extend_from_slice(&u);
    });
    Ok((phi, y))
}
