//! Sums over the passes: the cost, the statistics' sums, the robust scale, and the full
//! residual and Jacobian matrices for diagnostics (the normal equations: `normal`).

use super::accumulate::{Accumulator, Sums};
use super::batches::BlockScores;
use super::gram::{dot, gram, weighted_square_sum};
use super::local::{Pass, RawSample, ResidualFilter, columns};
use super::{Loss, PemProblem};
use crate::error::Result;
use crate::estimate::solver::Root;
use crate::model::BLOCK_LEN;
use crate::model::GreyBoxModel;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// The most numbers (rows × free parameters) of a Jacobian that
/// [`PemProblem::root`] keeps: 2²⁰, 8 MiB; a larger problem gives no root.
pub const ROOT_MAX_ENTRIES: usize = 1 << 20;

/// An experiment's Gram matrices in its local columns (row-major m × m, upper triangle):
/// `JᵀWJ`, the bread, and each output's meat.
struct LocalGrams {
    jtj: Vec<f64>,
    bread: Vec<f64>,
    meat: Vec<Vec<f64>>,
    /// Each output's unweighted Gram (unit sample weights, quadratic loss).
    unit: Vec<Vec<f64>>,
}

impl LocalGrams {
    fn new(ny: usize, m: usize) -> Self {
        let z = vec![0.0; m * m];
        Self { jtj: z.clone(), bread: z.clone(), meat: vec![z.clone(); ny], unit: vec![z; ny] }
    }
}

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// Cost `V(p)` only (simulation without sensitivities).
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn cost(&self, p: &DVector<f64>) -> Result<f64> {
        let ny = self.model.n_outputs();
        let parts: Vec<Result<f64>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| {
                let mut cost = 0.0;
                let quadratic = matches!(self.loss, Loss::Quadratic);
                self.pass_blocks(e, p, Pass::COST, |ch| {
                    for i in 0..ny {
                        let lambda = self.output_weights[i];
                        if quadratic {
                            cost += 0.5 * lambda * weighted_square_sum(ch.eps(i), ch.beta());
                            continue;
                        }
                        for (&ek, &bk) in ch.eps(i).iter().zip(ch.beta()) {
                            cost += bk * lambda * self.loss.eval(i, ek).0;
                        }
                    }
                    Ok(())
                })?;
                Ok(cost)
            })
            .collect();
        parts.into_iter().sum()
    }

    /// Weighted residuals `√w ε` stacked `[e][k][i]` and the Jacobian `√w ∂ŷ/∂p`
    /// (`N_total n_y × n_free`): the full matrices (quadratic-loss view), for tests,
    /// diagnostics and the [`root`](Self::root) of a problem that keeps J; the normal
    /// equations never form them.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn residuals_and_jacobian(&self, p: &DVector<f64>) -> Result<(DVector<f64>, DMatrix<f64>)> {
        let np = self.free.len();
        let mut r = Vec::new();
        let mut rows: Vec<f64> = Vec::new();
        for e in 0..self.terms.len() {
            self.pass(e, p, Pass::CRITERION, |_, eps, w, jac| {
                for i in 0..eps.len() {
                    let sw = w[i].sqrt();
                    r.push(sw * eps[i]);
                    rows.extend(jac[i * np..(i + 1) * np].iter().map(|v| sw * v));
                }
            })?;
        }
        let m = r.len();
        Ok((DVector::from_vec(r), DMatrix::from_row_slice(m, np, &rows)))
    }

    /// [`LeastSquares::root`](crate::estimate::LeastSquares::root): the QR factors of
    /// [`residuals_and_jacobian`](Self::residuals_and_jacobian) (the criterion's residuals
    /// and Jacobian, prefiltered where it is) where the problem [keeps
    /// J](Self::keeps_root); `None` otherwise. A pass of its own at p.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn root(&self, p: &DVector<f64>) -> Result<Option<Root>> {
        if !self.keeps_root() {
            return Ok(None);
        }
        let (e, j) = self.residuals_and_jacobian(p)?;
        Root::from_jacobian(j, &e).map(Some)
    }

    /// Whether the problem keeps its Jacobian for [`root`](Self::root): a static model (no
    /// state: a dynamic model's record is long, and J would cost a pass per point), the
    /// quadratic loss, a dense `JᵀWJ`, and at most [`ROOT_MAX_ENTRIES`] numbers in J.
    pub fn keeps_root(&self) -> bool {
        if self.model.n_states() > 0 || self.layout.is_some() || !matches!(self.loss, Loss::Quadratic) {
            return false;
        }
        let ny = self.model.n_outputs();
        let rows: usize = self.terms.iter().map(|t| ny * t.prep.n).sum();
        rows.saturating_mul(self.free.len()) <= ROOT_MAX_ENTRIES
    }

    /// Sums for the statistics of a fit at p (one pass per experiment).
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn sums(&self, p: &DVector<f64>) -> Result<Sums> {
        let (ny, np) = (self.model.n_outputs(), self.free.len());
        let mut acc = match &self.layout {
            Some(layout) => Accumulator::structured(ny, layout),
            None => Accumulator::new(ny, np),
        };
        let kept = self.best.at(p);
        for e in 0..self.terms.len() {
            let term = &self.terms[e];
            // Shift by the first measurement to keep Σy² − (Σy)²/n free of cancellation.
            let mut y0 = vec![0.0; ny];
            term.prep.y_at(0, &mut y0);
            acc.start_experiment(&y0);
            acc.add_moments(&term.prep.y, self.first_sample(e));
            match self.prefilters.get(e) {
                None if let Some(g) = kept.as_ref().map(|k| &k[e]) => self.kept_sums(e, p, g, &mut acc)?,
                None => self.block_sums(e, p, &mut acc)?,
                Some(l) => {
                    // The criterion sees L(q)ε; under white raw residuals e the score is
                    // J_fᵀ W L e, whose covariance is σ² gᵀg with g = Lᵀ (W J_f): the
                    // time-reversed filter applied to the weighted filtered Jacobian.
                    let mut raw: Vec<RawSample> = Vec::new();
                    self.pass(e, p, Pass::RAW, |k, eps, w, jac| {
                        raw.push((k, eps.to_vec(), w.to_vec(), jac.to_vec()))
                    })?;
                    for i in 0..ny {
                        acc.add_residuals(i, &raw.iter().map(|r| r.1[i]).collect::<Vec<_>>());
                    }
                    let sections = l.sections().len();
                    let mut filter = ResidualFilter::new(l, ny, np);
                    let mut weighted = vec![vec![0.0; raw.len()]; ny * np];
                    let mut scores = vec![DVector::zeros(np); raw.len()];
                    for (n, (_, eps, w, jac)) in raw.iter_mut().enumerate() {
                        let mut eps_f = eps.clone();
                        for i in 0..ny {
                            filter.apply(i, &mut eps_f[i], &mut jac[i * np..(i + 1) * np]);
                        }
                        acc.sample(&self.loss, &eps_f, eps, w, jac);
                        for i in 0..ny {
                            let (_, psi, _, dpsi) = self.loss.eval(i, eps_f[i]);
                            for a in 0..np {
                                weighted[i * np + a][n] = w[i] * dpsi * jac[i * np + a];
                                scores[n][a] += w[i] * psi * jac[i * np + a];
                            }
                        }
                    }
                    acc.add_sample_scores(&scores);
                    for i in 0..ny {
                        let g: Vec<Vec<f64>> = (0..np)
                            .map(|a| {
                                let mut z = vec![[0.0; 2]; sections];
                                let mut col: Vec<f64> =
                                    weighted[i * np + a].iter().rev().map(|&v| l.step(&mut z, v)).collect();
                                col.reverse();
                                col
                            })
                            .collect();
                        let mut row = vec![0.0; np];
                        for n in 0..raw.len() {
                            for (r, col) in row.iter_mut().zip(&g) {
                                *r = col[n];
                            }
                            acc.add_meat(i, 1.0, &row);
                        }
                    }
                }
            }
            acc.end_experiment();
        }
        Ok(acc.finish(&self.loss, !self.prefilters.is_empty()))
    }

    /// Experiment e's statistics sums without a prefilter, a block at a time: the
    /// residual sums and the Gram matrices (`JᵀWJ`, the bread, each output's meat) in the
    /// experiment's local columns, mapped once at the end; the raw residuals stream into
    /// the whiteness test's lag sums.
    fn block_sums(&self, e: usize, p: &DVector<f64>, acc: &mut Accumulator) -> Result<()> {
        let ny = self.model.n_outputs();
        let huber = matches!(self.loss, Loss::Huber { .. });
        let weighted = self.terms[e].weights.is_some();
        let mut local: Option<LocalGrams> = None;
        let (mut w, mut wb, mut wm) = (vec![0.0; BLOCK_LEN], vec![0.0; BLOCK_LEN], vec![0.0; BLOCK_LEN]);
        // w ψ(ε) of a block, and the block's score in the local columns.
        let (mut wpsi, mut score) = (vec![0.0; BLOCK_LEN], Vec::new());
        let mut scores = BlockScores::default();
        let map = self.pass_blocks(e, p, Pass::CRITERION, |ch| {
            let g = local.get_or_insert_with(|| {
                scores = BlockScores::new(ch.m);
                score = vec![0.0; ch.m];
                LocalGrams::new(ny, ch.m)
            });
            let n = ch.len - ch.lo;
            acc.add_samples(n);
            score.fill(0.0);
            for i in 0..ny {
                let lambda = self.output_weights[i];
                let eps = ch.eps(i);
                acc.add_residuals(i, eps);
                let mut spill = Vec::new();
                let cols = columns(ch, i, None, &mut spill);
                let sse = dot(eps, eps);
                if !weighted && !huber {
                    // Unit sample weights, quadratic loss: w = Λ_i, the bread is JᵀWJ and
                    // the meat Λ_i JᵀWJ; one unweighted Gram serves all three.
                    acc.add_output_sums(i, 0.5 * lambda * sse, lambda * sse, sse, sse, n);
                    gram(cols.as_ref(), None, &mut g.unit[i]);
                    for (s, c) in score.iter_mut().zip(cols.as_ref()) {
                        *s += lambda * dot(c, eps);
                    }
                    continue;
                }
                let mut cost = 0.0;
                for (t, (&ek, &bk)) in eps.iter().zip(ch.beta()).enumerate() {
                    let (rho, psi, _, dpsi) = self.loss.eval(i, ek);
                    let wi = bk * lambda;
                    if huber {
                        cost += wi * rho;
                    }
                    w[t] = wi;
                    wb[t] = wi * dpsi;
                    wm[t] = if huber { wi * wi * psi * psi } else { wi * wi };
                    wpsi[t] = wi * psi;
                }
                for (s, c) in score.iter_mut().zip(cols.as_ref()) {
                    *s += dot(c, &wpsi[..n]);
                }
                let e2w = weighted_square_sum(eps, &w[..n]);
                if !huber {
                    cost = 0.5 * e2w;
                }
                let (sse_live, n_live) = if weighted {
                    eps.iter()
                        .zip(&w[..n])
                        .filter(|(_, w)| **w > 0.0)
                        .fold((0.0, 0), |(s, c), (e, _)| (s + e * e, c + 1))
                } else {
                    (sse, n)
                };
                acc.add_output_sums(i, cost, e2w, sse, sse_live, n_live);
                gram(cols.as_ref(), Some(&w[..n]), &mut g.jtj);
                if huber {
                    gram(cols.as_ref(), Some(&wb[..n]), &mut g.bread);
                }
                gram(cols.as_ref(), Some(&wm[..n]), &mut g.meat[i]);
            }
            scores.push(n, &score);
            Ok(())
        })?;
        acc.add_block_scores(&map, &scores);
        if let Some(mut g) = local {
            for (i, unit) in g.unit.iter().enumerate() {
                let lambda = self.output_weights[i];
                for (v, u) in g.jtj.iter_mut().zip(unit) {
                    *v += lambda * u;
                }
                for (v, u) in g.meat[i].iter_mut().zip(unit) {
                    *v += lambda * lambda * u;
                }
            }
            if !huber {
                g.bread.clone_from(&g.jtj);
            }
            acc.add_local(&map, &g.jtj, &g.bread, &g.meat);
        }
        Ok(())
    }
}
