//! The normal-equation pass: the cost, `JᵀWJ` and `JᵀWψ` at a point, one pass per
//! experiment (in parallel, summed in experiment order), dense or by the blocks of the
//! problem's arrowhead layout.

use super::batches::BlockScores;
use super::gram::gram;
use super::kept::{ExperimentGrams, Gather, ResidualStreams};
use super::local::{LocalMap, Pass, columns, scatter_arrow, scatter_gram};
use super::{Loss, NormalEquations, PemProblem};
use crate::error::Result;
use crate::estimate::arrowhead::{ArrowLayout, Arrowhead};
use crate::model::BLOCK_LEN;
use crate::model::GreyBoxModel;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

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
        self.normal_equations_bounded(p, gather, f64::INFINITY)?
            .ok_or_else(|| crate::Error::Solver("a pass without a bound was abandoned".into()))
    }

    /// [`normal_equations_gathering`](Self::normal_equations_gathering), abandoned (`None`)
    /// once an experiment's running cost exceeds `bound`: the whole cost would then exceed
    /// it too (every term is at least 0, and a floating-point sum of such terms never
    /// decreases), so a `Some` is the unbounded pass's result to the bit.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub(crate) fn normal_equations_bounded(
        &self,
        p: &DVector<f64>,
        gather: Gather,
        bound: f64,
    ) -> Result<Option<NormalEquations>> {
        let np = self.free.len();
        if let Some(layout) = &self.layout {
            return self.structured_normal_equations(p, gather, layout, bound);
        }
        let parts: Vec<Result<_>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| {
                let Some(part) = self.experiment_normal_equations(e, p, gather, bound)? else {
                    return Ok(None);
                };
                let (jtj, jtr) = part.dense(np);
                Ok(Some((part.cost, jtj, jtr, part.grams)))
            })
            .collect();
        let (mut cost, mut jtj, mut jtr) = (0.0, DMatrix::zeros(np, np), DVector::zeros(np));
        let mut grams = Vec::with_capacity(parts.len());
        for part in parts {
            let Some((c, j, r, g)) = part? else { return Ok(None) };
            cost += c;
            jtj += j;
            jtr += r;
            grams.extend(g);
        }
        jtj.fill_lower_triangle_with_upper_triangle();
        if grams.len() == self.terms.len() {
            self.best.offer(p, cost, grams);
        }
        Ok(Some(NormalEquations { cost, jtj: jtj.into(), jtr }))
    }

    /// [`normal_equations_bounded`](Self::normal_equations_bounded) with `JᵀWJ` kept
    /// by the blocks of its arrowhead `layout`: every experiment's local Grams are added
    /// into its own block, its coupling to the shared columns and the shared block, in
    /// experiment order (identical for any thread count); nothing n_free × n_free is formed.
    fn structured_normal_equations(
        &self,
        p: &DVector<f64>,
        gather: Gather,
        layout: &std::sync::Arc<ArrowLayout>,
        bound: f64,
    ) -> Result<Option<NormalEquations>> {
        let parts: Vec<Result<Option<Partial>>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| self.experiment_normal_equations(e, p, gather, bound))
            .collect();
        let mut jtj = Arrowhead::zeros(std::sync::Arc::clone(layout));
        let (mut cost, mut jtr) = (0.0, DVector::zeros(self.free.len()));
        let mut grams = Vec::with_capacity(parts.len());
        for part in parts {
            let Some(part) = part? else { return Ok(None) };
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
        Ok(Some(NormalEquations { cost, jtj: jtj.into(), jtr }))
    }

    /// Experiment e's share of [`normal_equations`](Self::normal_equations): per output
    /// i the weighted Gram of its local columns and its residual,
    /// `G_i = Σ_k w_k [J_k ε_k]ᵀ[J_k ε_k]` with `w = β Λ_i ψ(ε)/ε` (IRLS weights; `ψ(ε) =
    /// ε` for the quadratic loss), holds `JᵀWJ` in its first m columns and `JᵀWψ` in its
    /// last (and, for the quadratic loss, twice the cost in its corner); with
    /// [`Gather::GramsAndResiduals`], and where the Grams are kept, the raw residuals' lag sums too.
    fn experiment_normal_equations(
        &self,
        e: usize,
        p: &DVector<f64>,
        gather: Gather,
        bound: f64,
    ) -> Result<Option<Partial>> {
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
        // Unit weights were summed without Λ_i: it scales the whole Gram.
        let scale_of = |i: usize| if unweighted { self.output_weights[i] } else { 1.0 };
        // The cost from the Grams `g` of m local columns (for the quadratic loss, twice the
        // cost in each corner) and the robust loss's own sum, in output order.
        let cost_of = |huber: f64, g: &[Vec<f64>], m: usize| {
            let corners = g.iter().enumerate().filter(|_| quadratic);
            corners.fold(huber, |cost, (i, gi)| cost + 0.5 * scale_of(i) * gi[m * (m + 1) + m])
        };
        let mut abandoned = false;
        let pass = self.pass_blocks(e, p, Pass::CRITERION, |ch| {
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
            // The running cost, summed as the final one below.
            if bound.is_finite() && cost_of(huber_cost, &g, ch.m) > bound {
                abandoned = true;
                return Err(crate::Error::Solver("the pass's cost exceeded its bound".into()));
            }
            Ok(())
        });
        let map = match pass {
            Err(_) if abandoned => return Ok(None),
            pass => pass?,
        };
        let (mut jtj, mut jtr) = (Vec::with_capacity(ny), Vec::with_capacity(ny));
        let m = map.len();
        let cost = cost_of(huber_cost, &g, m);
        let keep = keeps && !g.is_empty();
        for (i, gi) in g.iter().enumerate() {
            let scale = scale_of(i);
            let m1 = m + 1;
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
        Ok(Some(Partial { cost, map, jtj, jtr, grams }))
    }
}
