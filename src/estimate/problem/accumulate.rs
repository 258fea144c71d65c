//! Running sums at the estimate from which the statistics of a fit follow.

use super::Loss;
use super::batches::{BatchMeans, BlockScores, ScoreSeries, TARGET_BATCHES};
use super::lags::{LagStream, LagSums, WHITENESS_LAGS};
use super::local::LocalMap;
use super::local::{scatter_arrow, scatter_gram};
use crate::data::Values;
use crate::estimate::arrowhead::{ArrowLayout, Arrowhead};
use crate::estimate::solver::Gram;
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// Sums at the estimate from which the statistics of a fit follow.
#[derive(Clone, Debug)]
pub struct Sums {
    /// Cost `V`.
    pub cost: f64,
    /// Weighted residual sum of squares `Σ w ε²` (the E² of the error index).
    pub e2_weighted: f64,
    /// Unweighted residual sum of squares per output, length n_y.
    pub sse: Vec<f64>,
    /// The same over the samples with non-zero weight (the ones the criterion counts),
    /// length n_y.
    pub sse_live: Vec<f64>,
    /// Samples with non-zero weight per output, length n_y.
    pub n_live: Vec<usize>,
    /// Number of residual samples per output (same for every output).
    pub count: usize,
    /// `Σ (y − ȳ)²` per output, length n_y.
    pub sst: Vec<f64>,
    /// `JᵀWJ` (scaled space): the information matrix of the error index and diagnostics
    /// (by arrowhead blocks when the problem keeps them so, as the two below).
    pub jtj: Gram,
    /// Bread `A = Σ w ψ'(ε) JᵀJ` of the sandwich covariance `A⁻¹ B A⁻¹`.
    pub bread: Gram,
    /// Meat `B`: `Σ_i σ̂_i² Σ_k w² J_kiᵀJ_ki` (quadratic), `N/(N − n_free) Σ w² ψ² JᵀJ` (Huber);
    /// with a residual prefilter L(q), `Σ_i σ̂_i² gᵢᵀgᵢ` with `gᵢ = Lᵀ(W J_f)` (the
    /// time-reversed filter applied to the weighted filtered Jacobian) and σ̂ from the raw
    /// residuals: exact for white raw residuals.
    pub meat: Gram,
    /// The lag sums of the raw output errors `y − ŷ` of the counted samples, per output
    /// and experiment (`lag_sums[i][e]`, up to lag [`WHITENESS_LAGS`]): the whiteness test
    /// without the residuals kept or another simulation.
    pub lag_sums: Vec<Vec<LagSums>>,
    /// The batch-means long-run covariance of the score (the meat for residuals that are
    /// not white; see the `batches` module); `None` when too few batches can be formed.
    pub batch_means: Option<BatchMeans>,
    /// The score `Σ w ψ(ε) ∂ε/∂p` summed over every sample (length n_free, the optimiser's
    /// coordinates): the cost's gradient at p, for the convergence certificate.
    pub score: DVector<f64>,
}

/// Running sums of [`PemProblem::sums`](super::PemProblem::sums).
pub(crate) struct Accumulator {
    ny: usize,
    np: usize,
    cost: f64,
    e2w: f64,
    count: usize,
    n_e: usize,
    sse: Vec<f64>,
    // Raw residuals of samples with non-zero weight: the noise estimate ignores weighted-out ones.
    sse_live: Vec<f64>,
    n_live: Vec<usize>,
    y0: Vec<f64>,
    ey: Vec<f64>,
    ey2: Vec<f64>,
    sum_y: Vec<f64>,
    sum_y2: Vec<f64>,
    jtj: DMatrix<f64>,
    bread: DMatrix<f64>,
    // Per output: Σ w² J_iᵀJ_i (quadratic), Σ w² ψ² J_iᵀJ_i (Huber) or gᵀg (prefilter).
    meat_i: Vec<DMatrix<f64>>,
    lag_sums: Vec<Vec<LagSums>>,
    // The current experiment's raw residuals, per output.
    streams: Vec<LagStream>,
    // Or their lag sums, when a normal-equation pass gathered them.
    gathered: Option<Vec<LagSums>>,
    // Every experiment's score summed per block, for the batch means.
    scores: ScoreSeries,
    // JᵀWJ, the bread and each output's meat by arrowhead blocks (the dense ones above
    // are then empty).
    arrow: Option<(Arrowhead, Arrowhead, Vec<Arrowhead>)>,
}

impl Accumulator {
    pub(crate) fn new(ny: usize, np: usize) -> Self {
        Self::with_dense(ny, np, np)
    }

    /// Sums whose Gram matrices are kept by the blocks of the arrowhead `layout`.
    pub(crate) fn structured(ny: usize, layout: &Arc<ArrowLayout>) -> Self {
        let mut acc = Self::with_dense(ny, layout.n(), 0);
        let z = Arrowhead::zeros(Arc::clone(layout));
        acc.arrow = Some((z.clone(), z.clone(), vec![z; ny]));
        acc.scores = ScoreSeries::structured(Arc::clone(layout));
        acc
    }

    fn with_dense(ny: usize, np: usize, dense: usize) -> Self {
        let z = DMatrix::zeros(dense, dense);
        Self {
            ny,
            np,
            cost: 0.0,
            e2w: 0.0,
            count: 0,
            n_e: 0,
            sse: vec![0.0; ny],
            sse_live: vec![0.0; ny],
            n_live: vec![0; ny],
            y0: vec![0.0; ny],
            ey: vec![0.0; ny],
            ey2: vec![0.0; ny],
            sum_y: vec![0.0; ny],
            sum_y2: vec![0.0; ny],
            jtj: z.clone(),
            bread: z.clone(),
            meat_i: vec![z; ny],
            lag_sums: vec![Vec::new(); ny],
            streams: Vec::new(),
            gathered: None,
            scores: ScoreSeries::new(np),
            arrow: None,
        }
    }

    pub(crate) fn start_experiment(&mut self, y0: &[f64]) {
        self.y0.copy_from_slice(y0);
        self.ey.fill(0.0);
        self.ey2.fill(0.0);
        self.n_e = 0;
        self.gathered = None;
        self.streams = (0..self.ny).map(|_| LagStream::new(WHITENESS_LAGS)).collect();
    }

    /// One sample: `eps` the residual the criterion sees (filtered or not), `raw` the
    /// output error itself, `jac` the criterion's Jacobian (row-major n_y × n_free).
    pub(crate) fn sample(&mut self, loss: &Loss, eps: &[f64], raw: &[f64], w: &[f64], jac: &[f64]) {
        let np = self.np;
        self.n_e += 1;
        for i in 0..self.ny {
            let (rho, _, _, dpsi) = loss.eval(i, eps[i]);
            let live = w[i] > 0.0;
            self.add_output_sums(
                i,
                w[i] * rho,
                w[i] * eps[i] * eps[i],
                raw[i] * raw[i],
                if live { raw[i] * raw[i] } else { 0.0 },
                usize::from(live),
            );
            let row = &jac[i * np..(i + 1) * np];
            for a in 0..np {
                for b in a..np {
                    let jj = row[a] * row[b];
                    self.jtj[(a, b)] += w[i] * jj;
                    self.bread[(a, b)] += w[i] * dpsi * jj;
                }
            }
        }
    }

    /// Counts `n` more samples of the current experiment.
    pub(crate) fn add_samples(&mut self, n: usize) {
        self.n_e += n;
    }

    /// Adds output i's sums over some samples: cost, `Σ w ε²`, `Σ raw²`, and `Σ raw²` and
    /// the count over the samples with non-zero weight.
    pub(crate) fn add_output_sums(
        &mut self,
        i: usize,
        cost: f64,
        e2w: f64,
        sse: f64,
        sse_live: f64,
        n_live: usize,
    ) {
        self.cost += cost;
        self.e2w += e2w;
        self.sse[i] += sse;
        self.sse_live[i] += sse_live;
        self.n_live[i] += n_live;
    }

    /// Adds the output moments of the current experiment (its measured outputs `y`, n_y
    /// columns of length N, from sample `first` on) about its first measurement.
    pub(crate) fn add_moments(&mut self, y: &[Values], first: usize) {
        for (i, (ey, ey2)) in self.ey.iter_mut().zip(self.ey2.iter_mut()).enumerate() {
            let y0 = self.y0[i];
            let (mut s, mut s2) = ([0.0f64; 4], [0.0f64; 4]);
            // Sample n of the counted ones adds to lane n mod 4, four samples at a time.
            let quads = y[i].get(first..).unwrap_or_default().chunks_exact(4);
            let rest = quads.remainder();
            for q in quads {
                for l in 0..4 {
                    let d = q[l] - y0;
                    s[l] += d;
                    s2[l] += d * d;
                }
            }
            for (l, v) in rest.iter().enumerate() {
                let d = v - y0;
                s[l] += d;
                s2[l] += d * d;
            }
            *ey += (s[0] + s[1]) + (s[2] + s[3]);
            *ey2 += (s2[0] + s2[1]) + (s2[2] + s2[3]);
        }
    }

    /// Streams output i's next raw output errors of the current experiment (in time
    /// order) into its lag sums.
    pub(crate) fn add_residuals(&mut self, i: usize, residuals: &[f64]) {
        self.streams[i].push(residuals);
    }

    /// Adds an experiment's Gram matrices in its local columns (row-major m × m, upper
    /// triangle; `meat` one per output), chained to the optimiser's coordinates by `map`.
    pub(crate) fn add_local(&mut self, map: &LocalMap, jtj: &[f64], bread: &[f64], meat: &[Vec<f64>]) {
        if let Some((a_jtj, a_bread, a_meat)) = &mut self.arrow {
            scatter_arrow(map, jtj, a_jtj);
            scatter_arrow(map, bread, a_bread);
            for (mi, local) in a_meat.iter_mut().zip(meat) {
                scatter_arrow(map, local, mi);
            }
            return;
        }
        scatter_gram(map, jtj, &mut self.jtj);
        scatter_gram(map, bread, &mut self.bread);
        for (mi, local) in self.meat_i.iter_mut().zip(meat) {
            scatter_gram(map, local, mi);
        }
    }

    /// Adds `m · row rowᵀ` to the meat of output i (upper triangle).
    pub(crate) fn add_meat(&mut self, i: usize, m: f64, row: &[f64]) {
        for a in 0..self.np {
            for b in a..self.np {
                self.meat_i[i][(a, b)] += m * row[a] * row[b];
            }
        }
    }

    /// Adds the current experiment's block scores, in its local columns chained by `map`.
    pub(crate) fn add_block_scores(&mut self, map: &LocalMap, scores: &BlockScores) {
        self.scores.add(map, scores);
    }

    /// Adds the current experiment's per-sample scores (n_free each, in time order).
    pub(crate) fn add_sample_scores(&mut self, scores: &[nalgebra::DVector<f64>]) {
        self.scores.add_samples(scores, crate::model::BLOCK_LEN);
    }

    /// Sets the current experiment's lag sums, one per output, gathered elsewhere (the
    /// normal-equation pass at the same point): its residuals are not streamed here.
    pub(crate) fn add_lag_sums(&mut self, sums: Vec<LagSums>) {
        self.gathered = Some(sums);
    }

    pub(crate) fn end_experiment(&mut self) {
        let n = self.n_e as f64;
        self.count += self.n_e;
        let streams = std::mem::take(&mut self.streams);
        let sums: Vec<LagSums> = match self.gathered.take() {
            Some(sums) => sums,
            None => streams.into_iter().map(LagStream::finish).collect(),
        };
        for (all, s) in self.lag_sums.iter_mut().zip(sums) {
            all.push(s);
        }
        for i in 0..self.ny {
            // Pool about the grand mean over all experiments.
            let y0 = self.y0[i];
            self.sum_y[i] += self.ey[i] + n * y0;
            self.sum_y2[i] += self.ey2[i] + 2.0 * y0 * self.ey[i] + n * y0 * y0;
        }
    }

    pub(crate) fn finish(mut self, loss: &Loss, prefiltered: bool) -> Sums {
        let (ny, np, n) = (self.ny, self.np, self.count as f64);
        let sst = (0..ny).map(|i| (self.sum_y2[i] - self.sum_y[i] * self.sum_y[i] / n).max(0.0)).collect();
        let factor = |i: usize| {
            let live = self.n_live[i] as f64;
            let dof = (live - np as f64 / ny as f64).max(1.0);
            match loss {
                // Huber without prefilter: ψ² is already in the meat.
                Loss::Huber { .. } if !prefiltered => live / dof,
                // σ̂_i² = E_i²/(N − n_free/n_y) of the raw residuals with non-zero weight.
                _ => self.sse_live[i] / dof,
            }
        };
        let (jtj, bread, meat): (Gram, Gram, Gram) = match self.arrow.take() {
            Some((jtj, bread, meat_i)) => {
                let mut meat = Arrowhead::zeros(Arc::clone(jtj.layout()));
                for (i, mi) in meat_i.iter().enumerate() {
                    meat.add_scaled(mi, factor(i));
                }
                (jtj.into(), bread.into(), meat.into())
            }
            None => {
                let mut meat = DMatrix::zeros(np, np);
                for (i, mi) in self.meat_i.iter().enumerate() {
                    meat += mi * factor(i);
                }
                for m in [&mut self.jtj, &mut self.bread, &mut meat] {
                    m.fill_lower_triangle_with_upper_triangle();
                }
                (self.jtj.into(), self.bread.into(), meat.into())
            }
        };
        Sums {
            cost: self.cost,
            e2_weighted: self.e2w,
            sse: self.sse,
            sse_live: self.sse_live,
            n_live: self.n_live,
            count: self.count,
            sst,
            jtj,
            bread,
            meat,
            lag_sums: self.lag_sums,
            batch_means: self.scores.batch_means(TARGET_BATCHES),
            score: self.scores.total(),
        }
    }
}
