//! The normal-equation pass at the lowest cost met so far, kept for the statistics.
//!
//! With the quadratic loss, unit sample weights and no prefilter, the statistics of a fit
//! (MODEL.md §5) need, besides the raw residuals, only sums that the normal-equation pass
//! at the estimate has already formed: each output's Gram of the local Jacobian columns
//! and its residual (`JᵀJ`, `Jᵀε`, `εᵀε` per output). The solver's estimate is the point
//! of lowest cost it evaluated, so the problem keeps that pass's Grams, and
//! [`PemProblem::sums`](super::PemProblem::sums) at that very point (compared bit by bit)
//! takes them instead of a second pass with sensitivities. A pass the solver expects to be
//! its last ([`LeastSquares::normal_equations_likely_last`]) also streams the raw
//! residuals into the whiteness test's lag sums: if it is the estimate, the statistics run
//! no pass at all; if not, they cost that pass a few ns a sample (the lag products).
//!
//! [`LeastSquares::normal_equations_likely_last`]: crate::estimate::solver::LeastSquares::normal_equations_likely_last

use super::PemProblem;
use super::accumulate::Accumulator;
use super::batches::BlockScores;
use super::lags::{LagStream, LagSums, WHITENESS_LAGS};
use super::pass::{Chunk, LocalMap, Pass};
use crate::error::Result;
use crate::model::GreyBoxModel;
use nalgebra::DVector;
use std::sync::Mutex;

/// One experiment's Grams from a normal-equation pass: per output i the row-major
/// `(m + 1) × (m + 1)` upper triangle of `Σ_k [J_k ε_k]ᵀ[J_k ε_k]` over its m local columns
/// and its residual (unit weights, without Λ_i), and the local columns' map; and the raw
/// residuals' sums when the pass gathered them.
#[derive(Clone, Debug)]
pub(crate) struct ExperimentGrams {
    pub map: LocalMap,
    pub grams: Vec<Vec<f64>>,
    pub residuals: Option<ResidualSums>,
    /// The score summed over each block of the pass (the batch means' atoms).
    pub scores: BlockScores,
}

/// What a normal-equation pass keeps for the statistics, where they can take it (see the
/// module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Gather {
    /// Its Grams.
    Grams,
    /// Its Grams and the raw residuals' sums (the pass the solver expects to be its last).
    GramsAndResiduals,
}

/// What the statistics take of an experiment's raw residuals: the number of samples
/// counted and each output's lag sums (up to [`WHITENESS_LAGS`]).
#[derive(Clone, Debug)]
pub(crate) struct ResidualSums {
    n: usize,
    lags: Vec<LagSums>,
}

/// [`ResidualSums`] gathered block by block, in time order.
pub(crate) struct ResidualStreams {
    n: usize,
    streams: Vec<LagStream>,
}

impl ResidualStreams {
    /// Empty streams for `ny` outputs.
    pub(crate) fn new(ny: usize) -> Self {
        Self { n: 0, streams: (0..ny).map(|_| LagStream::new(WHITENESS_LAGS)).collect() }
    }

    /// Takes a block's counted residuals (raw: the pass has no prefilter).
    pub(crate) fn push(&mut self, ch: &Chunk<'_>) {
        self.n += ch.len - ch.lo;
        for (i, s) in self.streams.iter_mut().enumerate() {
            s.push(ch.eps(i));
        }
    }

    pub(crate) fn finish(self) -> ResidualSums {
        ResidualSums { n: self.n, lags: self.streams.into_iter().map(LagStream::finish).collect() }
    }
}

/// The Grams of the lowest-cost pass evaluated so far and its point p.
#[derive(Debug)]
struct Kept {
    p: DVector<f64>,
    cost: f64,
    experiments: Vec<ExperimentGrams>,
}

/// The kept pass (thread-safe: passes run from any thread of the pool).
#[derive(Debug, Default)]
pub(crate) struct BestPass(Mutex<Option<Kept>>);

impl BestPass {
    /// Keeps the pass at p of cost `cost` when it is lower than the kept one's.
    pub(crate) fn offer(&self, p: &DVector<f64>, cost: f64, experiments: Vec<ExperimentGrams>) {
        if !cost.is_finite() {
            return;
        }
        let mut kept = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if kept.as_ref().is_none_or(|k| cost < k.cost) {
            *kept = Some(Kept { p: p.clone(), cost, experiments });
        }
    }

    /// The kept Grams when they were taken at exactly p (every entry the same bits).
    pub(crate) fn at(&self, p: &DVector<f64>) -> Option<Vec<ExperimentGrams>> {
        let kept = self.0.lock().unwrap_or_else(|e| e.into_inner());
        let k = kept.as_ref()?;
        same_point(&k.p, p).then(|| k.experiments.clone())
    }

    /// Forgets the kept pass (the map from p to θ changed).
    pub(crate) fn clear(&self) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }
}

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// Whether [`sums`](PemProblem::sums) at p takes every sum from a pass already made
    /// there (the normal-equation pass the solver flagged as its last, at exactly p: every
    /// entry the same bits), so that the statistics simulate nothing.
    pub fn statistics_kept(&self, p: &DVector<f64>) -> bool {
        self.best.at(p).is_some_and(|k| k.iter().all(|e| e.residuals.is_some()))
    }

    /// Experiment e's statistics sums at p from the kept pass's Grams `kept` (quadratic
    /// loss, unit weights, no prefilter): the sums of the statistics pass, whose Gram of
    /// output i serves `JᵀWJ` (Λ_i G_i), the bread (the same) and the meat (Λ_i² G_i);
    /// the raw residuals' lag sums are the pass's when it gathered them; otherwise one
    /// simulation without sensitivities streams the raw residuals into them.
    ///
    /// # Errors
    /// Those of the simulation: invalid θ, [`crate::Error::SimulationDiverged`].
    pub(super) fn kept_sums(
        &self,
        e: usize,
        p: &DVector<f64>,
        kept: &ExperimentGrams,
        acc: &mut Accumulator,
    ) -> Result<()> {
        let ny = self.model.n_outputs();
        let n = match &kept.residuals {
            Some(r) => {
                acc.add_lag_sums(r.lags.clone());
                r.n
            }
            None => {
                let mut n = 0;
                self.pass_blocks(e, p, Pass::RAW_RESIDUALS, |ch| {
                    n += ch.len - ch.lo;
                    for i in 0..ny {
                        acc.add_residuals(i, ch.eps(i));
                    }
                })?;
                n
            }
        };
        acc.add_samples(n);
        let m = kept.map.len();
        let mut jtj = vec![0.0; m * m];
        let mut meat = vec![vec![0.0; m * m]; ny];
        for (i, (g, meat)) in kept.grams.iter().zip(meat.iter_mut()).enumerate() {
            let lambda = self.output_weights[i];
            let sse = g[m * (m + 1) + m];
            acc.add_output_sums(i, 0.5 * lambda * sse, lambda * sse, sse, sse, n);
            for a in 0..m {
                for b in a..m {
                    jtj[a * m + b] += lambda * g[a * (m + 1) + b];
                    meat[a * m + b] += lambda * lambda * g[a * (m + 1) + b];
                }
            }
        }
        acc.add_local(&kept.map, &jtj, &jtj, &meat);
        acc.add_block_scores(&kept.map, &kept.scores);
        Ok(())
    }
}

/// Whether two points of the parameter space are the same to the bit (every entry equal as
/// bits): a pass kept at one serves the other exactly, not approximately.
pub(crate) fn same_point(a: &DVector<f64>, b: &DVector<f64>) -> bool {
    a.len() == b.len() && a.iter().zip(b.iter()).all(|(x, y)| x.to_bits() == y.to_bits())
}
