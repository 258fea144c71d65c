//! What the statistics keep of a pass: its Grams per experiment ([`ExperimentGrams`]),
//! the raw residuals' sums, and the lowest-cost pass so far ([`BestPass`]).

use super::batches::BlockScores;
use super::lags::{LagStream, LagSums, WHITENESS_LAGS};
use super::local::{Chunk, LocalMap};
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
    pub(super) n: usize,
    pub(super) lags: Vec<LagSums>,
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

/// Whether two points of the parameter space are the same to the bit (every entry equal as
/// bits): a pass kept at one serves the other exactly, not approximately.
pub(crate) fn same_point(a: &DVector<f64>, b: &DVector<f64>) -> bool {
    a.len() == b.len() && a.iter().zip(b.iter()).all(|(x, y)| x.to_bits() == y.to_bits())
}
