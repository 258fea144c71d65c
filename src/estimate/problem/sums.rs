//! Sums over the passes: the cost, the normal equations, the statistics' sums, the robust
//! scale, and the full residual and Jacobian matrices for diagnostics.

use super::accumulate::{Accumulator, Sums};
use super::batches::BlockScores;
use super::gram::{dot, gram, weighted_square_sum};
use super::kept::{ExperimentGrams, Gather, ResidualStreams};
use super::local::{LocalMap, Pass, RawSample, ResidualFilter, columns};
use super::local::{scatter_arrow, scatter_gram};
use super::{Loss, NormalEquations, PemProblem};
use crate::error::Result;
use crate::estimate::arrowhead::{ArrowLayout, Arrowhead};
use crate::model::BLOCK_LEN;
use crate::model::GreyBoxModel;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

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

/// One experiment's share of the cost and normal equations: cost, its local columns, per
/// output the chained local `JᵀWJ` (row-major m × m, upper triangle) and `JᵀWψ` terms
/// (length m, each `dθ/dp` times the local sum); and its Grams when the statistics can take
/// them (see the `best` module).
struct Partial {
    cost: f64,
    map: LocalMap,
    jtj: Vec<Vec<f64>>,
    jtr: Vec<Vec<f64>>,
    grams: Option<ExperimentGrams>,
}

impl Partial {
    /// `JᵀWJ` (upper triangle, n_free × n_free) and `JᵀWψ` of the experiment alone.
    fn dense(&self, np: usize) -> (DMatrix<f64>, DVector<f64>) {
        let mut jtj = DMatrix::zeros(np, np);
        let mut jtr = DVector::zeros(np);
        for (local, terms) in self.jtj.iter().zip(&self.jtr) {
            scatter_gram(&self.map, local, &mut jtj);
            for (&g, v) in self.map.global.iter().zip(terms) {
                jtr[g] += v;
            }
        }
        (jtj, jtr)
    }
}

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// Cost `V(p)` and normal equations `JᵀWJ`, `JᵀWψ` in one pass per experiment
    /// (experiments in parallel, summed in a fixed order: identical for any thread count).
    ///
    /// # Errors
    /// Those of the simulation: invalid θ, [`crate::Error::SimulationDiverged`].
    pub fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        self.normal_equations_gathering(p, Gather::Grams)
    }

    /// [`normal_equations`](Self::normal_equations); with [`Gather::GramsAndResiduals`], the pass also
    /// streams the raw residuals into the whiteness test's lag sums and keeps them with its
    /// Grams, so that [`sums`](Self::sums) at this point needs no pass at all (see the
    /// `best` module).
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub(crate) fn normal_equations_gathering(
        &self,
        p: &DVector<f64>,
        gather: Gather,
    ) -> Result<NormalEquations> {
        let np = self.free.len();
        if let Some(layout) = &self.layout {
            return self.structured_normal_equations(p, gather, layout);
        }
        let parts: Vec<Result<_>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| {
                let part = self.experiment_normal_equations(e, p, gather)?;
                let (jtj, jtr) = part.dense(np);
                Ok((part.cost, jtj, jtr, part.grams))
            })
            .collect();
        let (mut cost, mut jtj, mut jtr) = (0.0, DMatrix::zeros(np, np), DVector::zeros(np));
        let mut grams = Vec::with_capacity(parts.len());
        for part in parts {
            let (c, j, r, g) = part?;
            cost += c;
            jtj += j;
            jtr += r;
            grams.extend(g);
        }
        jtj.fill_lower_triangle_with_upper_triangle();
        if grams.len() == self.terms.len() {
            self.best.offer(p, cost, grams);
        }
        Ok(NormalEquations { cost, jtj: jtj.into(), jtr })
    }

    /// [`normal_equations_gathering`](Self::normal_equations_gathering) with `JᵀWJ` kept
    /// by the blocks of its arrowhead `layout`: every experiment's local Grams are added
    /// into its own block, its coupling to the shared columns and the shared block, in
    /// experiment order (identical for any thread count); nothing n_free × n_free is formed.
    fn structured_normal_equations(
        &self,
        p: &DVector<f64>,
        gather: Gather,
        layout: &std::sync::Arc<ArrowLayout>,
    ) -> Result<NormalEquations> {
        let parts: Vec<Result<Partial>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| self.experiment_normal_equations(e, p, gather))
            .collect();
        let mut jtj = Arrowhead::zeros(std::sync::Arc::clone(layout));
        let (mut cost, mut jtr) = (0.0, DVector::zeros(self.free.len()));
        let mut grams = Vec::with_capacity(parts.len());
        for part in parts {
            let part = part?;
            cost += part.cost;
            for (local, terms) in part.jtj.iter().zip(&part.jtr) {
                scatter_arrow(&part.map, local, &mut jtj);
                for (&g, v) in part.map.global.iter().zip(terms) {
                    jtr[g] += v;
                }
            }
            grams.extend(part.grams);
        }
        if grams.len() == self.terms.len() {
            self.best.offer(p, cost, grams);
        }
        Ok(NormalEquations { cost, jtj: jtj.into(), jtr })
    }

    /// Experiment e's share of [`normal_equations`](Self::normal_equations): per output
    /// i the weighted Gram of its local columns and its residual,
    /// `G_i = Σ_k w_k [J_k ε_k]ᵀ[J_k ε_k]` with `w = β Λ_i ψ(ε)/ε` (IRLS weights; `ψ(ε) =
    /// ε` for the quadratic loss), holds `JᵀWJ` in its first m columns and `JᵀWψ` in its
    /// last (and, for the quadratic loss, twice the cost in its corner); with
    /// [`Gather::GramsAndResiduals`], and where the Grams are kept, the raw residuals' lag sums too.
    fn experiment_normal_equations(&self, e: usize, p: &DVector<f64>, gather: Gather) -> Result<Partial> {
        let ny = self.model.n_outputs();
        let quadratic = matches!(self.loss, Loss::Quadratic);
        let unweighted = quadratic && self.terms[e].weights.is_none();
        let keeps = unweighted && self.prefilters.is_empty();
        let mut streams = (gather == Gather::GramsAndResiduals && keeps).then(|| ResidualStreams::new(ny));
        let mut huber_cost = 0.0;
        let mut g: Vec<Vec<f64>> = Vec::new();
        let mut wq = vec![0.0; BLOCK_LEN];
        // The kept Grams' block scores (their Jᵀε column's growth per block), for the batch means.
        let mut scores: Option<BlockScores> = None;
        let mut before = Vec::new();
        let map = self.pass_blocks(e, p, Pass::CRITERION, |ch| {
            let m1 = ch.m + 1;
            if let Some(s) = streams.as_mut() {
                s.push(ch);
            }
            if g.is_empty() {
                g = vec![vec![0.0; m1 * m1]; ny];
                before = vec![0.0; ny * ch.m];
                scores = keeps.then(|| BlockScores::new(ch.m));
            }
            let n = ch.len - ch.lo;
            for (i, gi) in g.iter_mut().enumerate() {
                let lambda = self.output_weights[i];
                let mut spill = Vec::new();
                let cols = columns(ch, i, Some(ch.eps(i)), &mut spill);
                if unweighted {
                    gram(cols.as_ref(), None, gi);
                    continue;
                }
                for (t, (&ek, &bk)) in ch.eps(i).iter().zip(ch.beta()).enumerate() {
                    let w = bk * lambda;
                    if quadratic {
                        wq[t] = w;
                    } else {
                        let (rho, _, irls, _) = self.loss.eval(i, ek);
                        huber_cost += w * rho;
                        wq[t] = w * irls;
                    }
                }
                gram(cols.as_ref(), Some(&wq[..n]), gi);
            }
            if let Some(s) = scores.as_mut() {
                s.push_gram_growth(n, &g, &self.output_weights, &mut before);
            }
        })?;
        let (mut jtj, mut jtr) = (Vec::with_capacity(ny), Vec::with_capacity(ny));
        let mut cost = huber_cost;
        let m = map.len();
        let keep = keeps && !g.is_empty();
        for (i, gi) in g.iter().enumerate() {
            // Unit weights were summed without Λ_i: it scales the whole Gram.
            let scale = if unweighted { self.output_weights[i] } else { 1.0 };
            let m1 = m + 1;
            if quadratic {
                cost += 0.5 * scale * gi[m * m1 + m];
            }
            jtj.push(
                (0..m)
                    .flat_map(|a| (0..m).map(move |b| (a, b)))
                    .map(|(a, b)| scale * gi[a * m1 + b])
                    .collect(),
            );
            jtr.push((0..m).map(|a| map.dtheta[a] * scale * gi[a * m1 + m]).collect());
        }
        let residuals = streams.map(ResidualStreams::finish);
        let scores = scores.unwrap_or_default();
        let grams = keep.then(|| ExperimentGrams { map: map.clone(), grams: g, residuals, scores });
        Ok(Partial { cost, map, jtj, jtr, grams })
    }

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
