//! Sums over the passes: the cost, the normal equations, the statistics' sums, the robust
//! scale, and the full residual and Jacobian matrices for diagnostics.

use super::accumulate::{Accumulator, Sums};
use super::pass::{Pass, RawSample, ResidualFilter};
use super::{Loss, NormalEquations, PemProblem};
use crate::error::Result;
use crate::model::GreyBoxModel;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// One experiment's share of the cost and normal equations (cost, `JᵀWJ` row-major, `JᵀWψ`).
type Partial = (f64, Vec<f64>, Vec<f64>);

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// Cost `V(p)` and normal equations `JᵀWJ`, `JᵀWψ` in one pass per experiment
    /// (experiments in parallel, summed in a fixed order: identical for any thread count).
    ///
    /// # Errors
    /// Those of the simulation: invalid θ, [`Error::SimulationDiverged`].
    pub fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        let np = self.free.len();
        let parts: Vec<Result<Partial>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| {
                let mut cost = 0.0;
                let mut jtj = vec![0.0; np * np];
                let mut jtr = vec![0.0; np];
                self.pass(e, p, Pass::CRITERION, |_, eps, w, jac| {
                    for (i, (&ei, &wi)) in eps.iter().zip(w).enumerate() {
                        let (rho, psi, irls, _) = self.loss.eval(i, ei);
                        cost += wi * rho;
                        let row = &jac[i * np..(i + 1) * np];
                        for a in 0..np {
                            jtr[a] += wi * row[a] * psi;
                            let wa = wi * irls * row[a];
                            for b in a..np {
                                jtj[a * np + b] += wa * row[b];
                            }
                        }
                    }
                })?;
                Ok((cost, jtj, jtr))
            })
            .collect();
        let mut out = NormalEquations { cost: 0.0, jtj: DMatrix::zeros(np, np), jtr: DVector::zeros(np) };
        for part in parts {
            let (c, jtj, jtr) = part?;
            out.cost += c;
            for a in 0..np {
                out.jtr[a] += jtr[a];
                for b in a..np {
                    out.jtj[(a, b)] += jtj[a * np + b];
                }
            }
        }
        out.jtj.fill_lower_triangle_with_upper_triangle();
        Ok(out)
    }

    /// Cost `V(p)` only (simulation without sensitivities).
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn cost(&self, p: &DVector<f64>) -> Result<f64> {
        let parts: Vec<Result<f64>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| {
                let mut cost = 0.0;
                self.pass(e, p, Pass::COST, |_, eps, w, _| {
                    for (i, (&ei, &wi)) in eps.iter().zip(w).enumerate() {
                        cost += wi * self.loss.eval(i, ei).0;
                    }
                })?;
                Ok(cost)
            })
            .collect();
        parts.into_iter().sum()
    }

    /// Weighted residuals `√w ε` stacked `[e][k][i]` and the Jacobian `√w ∂ŷ/∂p`
    /// (`N_total n_y × n_free`): the full matrices, for tests and diagnostics only
    /// (quadratic-loss view; the default path never forms them).
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

    /// Sums for the statistics of a fit at p (one pass per experiment).
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn sums(&self, p: &DVector<f64>) -> Result<Sums> {
        let (ny, np) = (self.model.n_outputs(), self.free.len());
        let mut acc = Accumulator::new(ny, np);
        for e in 0..self.terms.len() {
            let term = &self.terms[e];
            // Shift by the first measurement to keep Σy² − (Σy)²/n free of cancellation.
            acc.start_experiment(term.prep.y_at(0, ny));
            match self.prefilters.get(e) {
                None => self.pass(e, p, Pass::CRITERION, |k, eps, w, jac| {
                    acc.sample(&self.loss, term.prep.y_at(k, ny), eps, eps, w, jac);
                    for i in 0..ny {
                        let psi = self.loss.eval(i, eps[i]).1;
                        let m = match self.loss {
                            Loss::Quadratic => w[i] * w[i],
                            Loss::Huber { .. } => w[i] * w[i] * psi * psi,
                        };
                        acc.add_meat(i, m, &jac[i * np..(i + 1) * np]);
                    }
                })?,
                Some(l) => {
                    // The criterion sees L(q)ε; under white raw residuals e the score is
                    // J_fᵀ W L e, whose covariance is σ² gᵀg with g = Lᵀ (W J_f): the
                    // time-reversed filter applied to the weighted filtered Jacobian.
                    let mut raw: Vec<RawSample> = Vec::new();
                    self.pass(e, p, Pass::RAW, |k, eps, w, jac| {
                        raw.push((k, eps.to_vec(), w.to_vec(), jac.to_vec()))
                    })?;
                    let sections = l.sections().len();
                    let mut filter = ResidualFilter::new(l, ny, np);
                    let mut weighted = vec![vec![0.0; raw.len()]; ny * np];
                    for (n, (k, eps, w, jac)) in raw.iter_mut().enumerate() {
                        let mut eps_f = eps.clone();
                        for i in 0..ny {
                            filter.apply(i, &mut eps_f[i], &mut jac[i * np..(i + 1) * np]);
                        }
                        acc.sample(&self.loss, term.prep.y_at(*k, ny), &eps_f, eps, w, jac);
                        for i in 0..ny {
                            let dpsi = self.loss.eval(i, eps_f[i]).3;
                            for a in 0..np {
                                weighted[i * np + a][n] = w[i] * dpsi * jac[i * np + a];
                            }
                        }
                    }
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

    /// Robust scale `1.4826 × MAD` of each output's residuals at p (length n_y), the
    /// standard deviation for Gaussian residuals (Huber 1981, 5.1).
    ///
    /// # Errors
    /// As [`cost`](Self::cost).
    pub fn robust_scale(&self, p: &DVector<f64>) -> Result<Vec<f64>> {
        let ny = self.model.n_outputs();
        let mut res: Vec<Vec<f64>> = vec![Vec::new(); ny];
        for e in 0..self.terms.len() {
            self.pass(e, p, Pass::RAW_RESIDUALS, |_, eps, _, _| {
                for (r, &v) in res.iter_mut().zip(eps) {
                    r.push(v);
                }
            })?;
        }
        Ok(res.into_iter().map(|r| 1.4826 * mad(r)).collect())
    }
}

/// Median absolute deviation from the median (0 for an empty slice).
fn mad(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let median = |v: &mut Vec<f64>| {
        let m = v.len() / 2;
        *v.select_nth_unstable_by(m, f64::total_cmp).1
    };
    let med = median(&mut v);
    for x in v.iter_mut() {
        *x = (*x - med).abs();
    }
    median(&mut v)
}
