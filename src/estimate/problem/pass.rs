//! One residual/sensitivity pass over an experiment: the single loop that the cost, the
//! normal equations, the statistics and the robust scale are sums over.

use super::PemProblem;
use crate::error::Result;
use crate::estimate::filter::Butterworth;
use crate::model::GreyBoxModel;
use crate::simulate::{SimOptions, simulate, visit_sensitivities};
use nalgebra::DVector;

/// What a pass computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Pass {
    /// Also the Jacobian `J_k = ∂ŷ_k/∂p` (forward sensitivities); otherwise `J_k` is empty.
    pub jacobian: bool,
    /// Run the residual prefilter L(q) over ε (and J), when the problem has one.
    pub filtered: bool,
}

impl Pass {
    /// Residuals and Jacobian as the criterion sees them.
    pub const CRITERION: Self = Self { jacobian: true, filtered: true };
    /// Residuals only, as the criterion sees them.
    pub const COST: Self = Self { jacobian: false, filtered: true };
    /// Raw residuals and Jacobian (no prefilter).
    pub const RAW: Self = Self { jacobian: true, filtered: false };
    /// Raw residuals only.
    pub const RAW_RESIDUALS: Self = Self { jacobian: false, filtered: false };
}

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// Runs `f(k, ε_k, w_k, J_k)` over every counted sample of experiment e
    /// ([`first_sample`](Self::first_sample) on), where `ε_k = y_k − ŷ_k` (length n_y),
    /// `w_k[i] = β_k Λ_i` and `J_k = ∂ŷ_k/∂p` is row-major `n_y × n_free` (empty without
    /// `mode.jacobian`): the one loop every sum of the problem is built from.
    ///
    /// # Errors
    /// Those of the simulation: invalid θ, [`crate::Error::SimulationDiverged`].
    pub(crate) fn pass<F>(&self, e: usize, p: &DVector<f64>, mode: Pass, mut f: F) -> Result<()>
    where
        F: FnMut(usize, &[f64], &[f64], &[f64]),
    {
        let term = &self.terms[e];
        let (ny, np) = (self.model.n_outputs(), if mode.jacobian { self.free.len() } else { 0 });
        let theta = self.theta(e, p);
        let (global, dtheta) = self.chain(e, p);
        let x0 = self.x0(e, p);
        let nx = x0.len();
        let x0_chain: Vec<(usize, f64)> = term
            .x0_free
            .map(|g| (0..nx).map(|i| (g + i, self.free[g + i].transform.dtheta_dp(p[g + i]))).collect())
            .unwrap_or_default();
        let mut eps = vec![0.0; ny];
        let mut jac = vec![0.0; ny * np];
        let mut w = vec![0.0; ny];
        let nth = theta.len();
        let first = self.first_sample(e);
        let mut filter =
            self.prefilters.get(e).filter(|_| mode.filtered).map(|l| ResidualFilter::new(l, ny, np));
        let mut visit = |k: usize, yhat: &[f64], dy: &[f64], dy0: &[f64]| {
            if k < first {
                return;
            }
            let y = term.prep.y_at(k, ny);
            let beta = term.weights.as_ref().map_or(1.0, |b| b[k]);
            jac.fill(0.0);
            for i in 0..ny {
                eps[i] = y[i] - yhat[i];
                w[i] = beta * self.output_weights[i];
                if np > 0 {
                    for j in 0..nth {
                        if let Some(g) = global[j] {
                            jac[i * np + g] += dy[i * nth + j] * dtheta[j];
                        }
                    }
                    for (m, &(g, d)) in x0_chain.iter().enumerate() {
                        jac[i * np + g] += dy0[i * nx + m] * d;
                    }
                }
                if let Some(l) = filter.as_mut() {
                    l.apply(i, &mut eps[i], &mut jac[i * np..(i + 1) * np]);
                }
            }
            f(k, &eps, &w, &jac);
        };
        if !mode.jacobian {
            let options = SimOptions { horizon: self.horizon, x0: Some(&x0), ..Default::default() };
            let yhat = simulate(self.model, &term.prep, &theta, &options)?;
            for k in 0..term.prep.n {
                visit(k, &yhat[k * ny..(k + 1) * ny], &[], &[]);
            }
            return Ok(());
        }
        let scale = self.fd_scale(e, p);
        let options = SimOptions {
            horizon: self.horizon,
            x0: Some(&x0),
            x0_sensitivity: term.x0_free.is_some(),
            fd_scale: Some(&scale),
        };
        visit_sensitivities(self.model, &term.prep, &theta, &options, visit)
    }
}

/// The residual prefilter L(q) run sample by sample over each output's residual and its
/// Jacobian row (one filter state per channel, from rest).
pub(crate) struct ResidualFilter<'f> {
    l: &'f Butterworth,
    eps: Vec<Vec<[f64; 2]>>,
    jac: Vec<Vec<[f64; 2]>>,
    np: usize,
}

impl<'f> ResidualFilter<'f> {
    /// States for `ny` residuals and `ny × np` Jacobian entries.
    pub(crate) fn new(l: &'f Butterworth, ny: usize, np: usize) -> Self {
        let sections = l.sections().len();
        Self { l, eps: vec![vec![[0.0; 2]; sections]; ny], jac: vec![vec![[0.0; 2]; sections]; ny * np], np }
    }

    /// Filters output i's residual and its Jacobian row (length n_free, or empty) in place.
    #[inline]
    pub(crate) fn apply(&mut self, i: usize, eps: &mut f64, row: &mut [f64]) {
        *eps = self.l.step(&mut self.eps[i], *eps);
        for (a, v) in row.iter_mut().enumerate() {
            *v = self.l.step(&mut self.jac[i * self.np + a], *v);
        }
    }
}

/// One unfiltered sample of a pass: `(k, ε, w, J)`.
pub(crate) type RawSample = (usize, Vec<f64>, Vec<f64>, Vec<f64>);
