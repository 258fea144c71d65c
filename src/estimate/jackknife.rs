//! The delete-one-batch jackknife covariance of an estimating-equation estimate (the
//! cluster jackknife, CV3): for equations `Σ_k Z_kᵀ ε_k(θ) = 0` with `M = Σ_k Z_kᵀ D_k`
//! and score `S = Σ_k Z_kᵀ ε_k` at the estimate θ̂, the estimate without batch g is one
//! Newton step from θ̂, `θ̂₋g = θ̂ − (M − M_g)⁻¹ (S − S_g)`, and
//! `V = (G − 1)/G Σ_g (θ̂₋g − θ̄)(θ̂₋g − θ̄)ᵀ` with θ̄ their mean; the intervals take Student t
//! with G − 1 degrees of freedom, as the batch means do.
//!
//! Batch means (`M⁻¹ B̂ M⁻ᵀ`, [`super::problem::BatchMeans`]) weigh every batch's score by
//! the same `M⁻¹`. When the information sits in a few batches (the transients of a drive
//! cycle, the low-speed samples that tell R_s), their scores are pulled towards the fit
//! and that covariance is too small: the spread of z was 1.2–1.35 on slow telemetry with
//! current noise. Deleting the batch from `M` too undoes this (the jackknife's
//! `(I − H_gg)⁻¹` leverage correction): MacKinnon & White, *J. Econometrics* 29 (1985)
//! 305–325; Bell & McCaffrey, *Survey Methodology* 28 (2002) 169–181; MacKinnon, Nielsen &
//! Webb, *J. Econometrics* 232 (2023) 272–299 (CV3, recommended over CV1 for few or
//! unbalanced clusters). Batches are those of the batch means ([`super::problem::partition`]).

use super::problem::{MIN_BATCHES, ScoreSeries, partition};
use nalgebra::{DMatrix, DVector};

/// Per-block `Σ Zᵀ D` (n_θ × n_θ) of the estimating equations, kept for the jackknife beside
/// the block scores the batch means keep ([`ScoreSeries`]), in the same blocks.
#[derive(Clone, Debug)]
pub(crate) struct BlockSums {
    nth: usize,
    len: usize,
    /// Per experiment, per block.
    experiments: Vec<Vec<DMatrix<f64>>>,
    /// The open block: its samples and `Σ Zᵀ D`.
    open_n: usize,
    open_m: DMatrix<f64>,
}

impl BlockSums {
    /// Empty sums for `nth` parameters in blocks of `len` samples (at least 1), the block
    /// length of the scores they go with.
    pub(crate) fn new(nth: usize, len: usize) -> Self {
        Self { nth, len: len.max(1), experiments: Vec::new(), open_n: 0, open_m: DMatrix::zeros(nth, nth) }
    }

    /// Starts an experiment (blocks never reach across experiments).
    pub(crate) fn start_experiment(&mut self) {
        self.close();
        self.experiments.push(Vec::new());
    }

    /// The open block's `Σ Zᵀ D` (n_θ × n_θ), for a sample's terms added before
    /// [`count`](Self::count).
    pub(crate) fn open_m_mut(&mut self) -> &mut DMatrix<f64> {
        &mut self.open_m
    }

    /// Ends one sample.
    pub(crate) fn count(&mut self) {
        self.open_n += 1;
        if self.open_n == self.len {
            self.close();
        }
    }

    /// Appends the open block to the current experiment, if it holds a sample.
    pub(crate) fn close(&mut self) {
        if self.open_n == 0 {
            return;
        }
        let m = std::mem::replace(&mut self.open_m, DMatrix::zeros(self.nth, self.nth));
        if self.experiments.is_empty() {
            // Samples counted before any experiment started: one experiment.
            self.experiments.push(Vec::new());
        }
        if let Some(e) = self.experiments.last_mut() {
            e.push(m);
        }
        self.open_n = 0;
    }

    /// Per batch of about `total/target` samples ([`partition`]): its samples, score sum
    /// `S_g` (n_θ) and `M_g = Σ Zᵀ D` (n_θ × n_θ), from the block scores `scores` (kept in the
    /// same blocks, in the optimiser's coordinates); `None` with fewer than [`MIN_BATCHES`]
    /// batches or blocks that do not match. Shared by the jackknife and the restricted
    /// intervals ([`super::restricted`]).
    pub(crate) fn batches(&self, scores: &ScoreSeries, target: usize) -> Option<Vec<BatchSums>> {
        let blocks: Vec<(&[usize], &[DVector<f64>])> = scores.plain_blocks().collect();
        let matched = blocks.len() == self.experiments.len()
            && blocks
                .iter()
                .zip(&self.experiments)
                .all(|((c, s), e)| c.len() == e.len() && s.len() == e.len());
        if !matched {
            return None;
        }
        let total: usize = blocks.iter().flat_map(|(c, _)| c.iter()).sum();
        let batches = partition(blocks.iter().map(|(c, _)| *c), total, target);
        if total == 0 || batches.len() < MIN_BATCHES {
            return None;
        }
        let nth = self.nth;
        Some(
            batches
                .iter()
                .map(|b| {
                    let counts = blocks[b.experiment].0;
                    BatchSums {
                        samples: counts[b.blocks.clone()].iter().chain(&counts[b.tail.clone()]).sum(),
                        score: b.sum(blocks[b.experiment].1, || DVector::zeros(nth)),
                        m: b.sum(&self.experiments[b.experiment], || DMatrix::zeros(nth, nth)),
                    }
                })
                .collect(),
        )
    }
}

/// The jackknife covariance (module documentation) at the estimate whose sums are `m`
/// (`M`, n_θ × n_θ) and `score` (`S`, n_θ), over the batches `batches`
/// ([`BlockSums::batches`]); `None` when `M − M_g` is singular for a batch (a batch that
/// alone determines a parameter).
pub(crate) fn jackknife_covariance(
    m: &DMatrix<f64>,
    score: &DVector<f64>,
    batches: &[BatchSums],
) -> Option<DMatrix<f64>> {
    let (g, nth) = (batches.len(), score.len());
    let mut shifts = Vec::with_capacity(g);
    for b in batches {
        let step = (m - &b.m).lu().solve(&(score - &b.score))?;
        if !step.iter().all(|v| v.is_finite()) {
            return None;
        }
        shifts.push(-step);
    }
    let mean = shifts.iter().fold(DVector::zeros(nth), |a, d| a + d) / g as f64;
    let mut v = DMatrix::zeros(nth, nth);
    for d in &shifts {
        let c = d - &mean;
        v += &c * c.transpose();
    }
    Some(v * ((g - 1) as f64 / g as f64))
}

/// One batch's sums ([`BlockSums::batches`]).
#[derive(Clone, Debug)]
pub(crate) struct BatchSums {
    /// Its samples.
    pub samples: usize,
    /// `S_g = Σ Zᵀ ε` over the batch (n_θ).
    pub score: DVector<f64>,
    /// `M_g = Σ Zᵀ D` over the batch (n_θ × n_θ).
    pub m: DMatrix<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::problem::BlockScores;

    /// Least squares `y = a + b x` as the estimating equations `Σ x_k (y_k − x_kᵀθ) = 0`:
    /// the one-step jackknife is exact for a linear model, so each deleted-batch estimate
    /// is the refit without the batch, and the covariance is the textbook jackknife's.
    #[test]
    fn the_jackknife_of_a_linear_fit_is_the_refits_spread() {
        let n = 400;
        let x: Vec<[f64; 2]> =
            (0..n).map(|k| [1.0, (k as f64 * 0.37).sin() * (1.0 + k as f64 / 100.0)]).collect();
        let y: Vec<f64> =
            (0..n).map(|k| 0.5 - 2.0 * x[k][1] + ((k * 7919) % 101) as f64 / 101.0 - 0.5).collect();
        let fit = |skip: &dyn Fn(usize) -> bool| {
            let (mut a, mut r) = (DMatrix::zeros(2, 2), DVector::zeros(2));
            for k in (0..n).filter(|&k| !skip(k)) {
                let v = DVector::from_row_slice(&x[k]);
                a += &v * v.transpose();
                r += &v * y[k];
            }
            a.lu().solve(&r).unwrap()
        };
        let theta = fit(&|_| false);
        let mut sums = BlockSums::new(2, 25);
        let mut blocks = BlockScores::with_len(2, 25);
        let (mut m, mut s) = (DMatrix::zeros(2, 2), DVector::zeros(2));
        sums.start_experiment();
        for k in 0..n {
            let v = DVector::from_row_slice(&x[k]);
            let e = y[k] - v.dot(&theta);
            // ε = y − xᵀθ: D = −xᵀ, Z = −xᵀ (signs as the IV sums take them).
            let zd = &v * v.transpose();
            m += &zd;
            *sums.open_m_mut() += &zd;
            let sc = &v * (-e);
            s += &sc;
            blocks.add(sc.as_slice());
            sums.count();
        }
        sums.close();
        blocks.close();
        let mut series = ScoreSeries::new(2);
        series.add_plain(&blocks);
        let v = jackknife_covariance(&m, &s, &sums.batches(&series, 16).unwrap()).unwrap();
        // 400 samples, blocks of 25: 16 batches of one block each.
        let refits: Vec<DVector<f64>> = (0..16).map(|g| fit(&|k| k / 25 == g)).collect();
        let mean = refits.iter().fold(DVector::zeros(2), |a, r| a + r) / 16.0;
        let mut want = DMatrix::zeros(2, 2);
        for r in &refits {
            want += (r - &mean) * (r - &mean).transpose();
        }
        want *= 15.0 / 16.0;
        for (a, b) in v.iter().zip(want.iter()) {
            approx::assert_relative_eq!(*a, *b, max_relative = 1e-9);
        }
        assert!(v[(1, 1)] > 0.0);
    }

    #[test]
    fn too_few_batches_give_none() {
        let mut sums = BlockSums::new(1, 10);
        let mut blocks = BlockScores::with_len(1, 10);
        sums.start_experiment();
        for _ in 0..50 {
            *sums.open_m_mut() += DMatrix::from_element(1, 1, 1.0);
            blocks.add(&[0.1]);
            sums.count();
        }
        sums.close();
        blocks.close();
        let mut series = ScoreSeries::new(1);
        series.add_plain(&blocks);
        assert!(sums.batches(&series, 32).is_none());
    }
}
