//! The score's long-run covariance by batch means, for residuals that are not white.
//!
//! The sandwich `A⁻¹ B A⁻¹` needs `B = Var(Σ_k s_k)`, the variance of the summed score
//! `s_k = Σ_i w_ki ψ(ε_ki) J_kiᵀ` (n_free). White residuals give `B = Σ_i σ̂_i² Σ_k w² J_kiᵀJ_ki`;
//! coloured ones (noise on an input, coloured measurement noise, a model error) make the
//! scores of neighbouring samples correlated and that `B` far too small. Batch means
//! estimate it without the per-sample scores: cut each experiment's samples into B
//! consecutive batches of about `N/B` samples, sum the score over each batch (`S_b`, which
//! a pass over the blocks forms anyway as its share of `JᵀWψ`), and take
//! `B̂ = B/(B − 1) Σ_b (S_b − (n_b/N) S)(S_b − (n_b/N) S)ᵀ` with `S = Σ_b S_b` (≈ 0 at the
//! estimate). With the number of batches held fixed, `(θ̂_j − θ_j)/se_j` is Student t with
//! `B − 1` degrees of freedom when the batches are long against the scores' correlation
//! time (the fixed-b view: Kiefer & Vogelsang, *Econometric Theory* 21 (2005) 1130–1164;
//! Ibragimov & Müller, *J. Bus. Econ. Stat.* 28 (2010) 453–468; batch means in simulation
//! output analysis: Schmeiser, *Oper. Res.* 30 (1982) 556–568). Blocks of the pass are the
//! atoms: a batch is a run of whole blocks of one experiment, so nothing per sample is kept.

use super::local::LocalMap;
use super::partition::partition;
use crate::estimate::arrowhead::{ArrowLayout, Arrowhead, LowRank};
use crate::model::BLOCK_LEN;
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// Batches the long-run covariance aims at (the t quantile of 31 degrees of freedom is
/// 2.04, 4 % above the normal one; more batches would shorten them against a slow
/// correlation).
pub const TARGET_BATCHES: usize = 32;

/// Fewest batches for which the batch-means covariance is given (t with 7 degrees of
/// freedom: 2.36).
pub const MIN_BATCHES: usize = 8;

/// One experiment's score summed over each block of a pass, in the experiment's local
/// columns (before the chain factor `dθ/dp`): block `c` counted `counts[c]` samples and
/// summed to `values[c m .. (c + 1) m]`.
#[derive(Clone, Debug)]
pub(crate) struct BlockScores {
    m: usize,
    counts: Vec<usize>,
    values: Vec<f64>,
    /// The block [`add`](Self::add) fills, and its samples so far.
    open: Vec<f64>,
    open_n: usize,
    /// Samples a block holds ([`BLOCK_LEN`] unless [`with_len`](Self::with_len)).
    len: usize,
}

impl Default for BlockScores {
    fn default() -> Self {
        Self::new(0)
    }
}

impl BlockScores {
    /// Empty sums for m local columns.
    pub(crate) fn new(m: usize) -> Self {
        Self::with_len(m, BLOCK_LEN)
    }

    /// Empty sums for m local columns in blocks of `len` samples (at least 1): shorter
    /// blocks than a pass's let a short record form its batches.
    pub(crate) fn with_len(m: usize, len: usize) -> Self {
        Self { m, counts: Vec::new(), values: Vec::new(), open: vec![0.0; m], open_n: 0, len: len.max(1) }
    }

    /// Adds one sample's score (length m) to the open block, then [`count`](Self::count)s it.
    pub(crate) fn add(&mut self, score: &[f64]) {
        for (o, v) in self.open.iter_mut().zip(score) {
            *o += v;
        }
        self.count();
    }

    /// The open block's sums (length m), for a sample's score added term by term before
    /// [`count`](Self::count).
    pub(crate) fn open_mut(&mut self) -> &mut [f64] {
        &mut self.open
    }

    /// Ends the current sample; the open block is appended once it holds its length's
    /// samples (and by [`close`](Self::close)).
    pub(crate) fn count(&mut self) {
        self.open_n += 1;
        if self.open_n == self.len {
            self.close();
        }
    }

    /// Appends the open block, if it holds a sample.
    pub(crate) fn close(&mut self) {
        if self.open_n > 0 {
            self.counts.push(self.open_n);
            self.values.extend_from_slice(&self.open);
            self.open.fill(0.0);
            self.open_n = 0;
        }
    }

    /// Appends one block's score sum (length m) over its `n` counted samples.
    pub(crate) fn push(&mut self, n: usize, score: &[f64]) {
        debug_assert_eq!(score.len(), self.m);
        self.counts.push(n);
        self.values.extend_from_slice(score);
    }

    /// Appends the last column of each output's running Gram `(m + 1) × (m + 1)` (its
    /// `Jᵀψ`, scaled by `scale[i]`) minus what it held before this block (`before`, updated).
    pub(crate) fn push_gram_growth(
        &mut self,
        n: usize,
        grams: &[Vec<f64>],
        scale: &[f64],
        before: &mut [f64],
    ) {
        let m = self.m;
        let m1 = m + 1;
        let mut s = vec![0.0; m];
        for ((g, &l), prev) in grams.iter().zip(scale).zip(before.chunks_exact_mut(m)) {
            for a in 0..m {
                let now = g[a * m1 + m];
                s[a] += l * (now - prev[a]);
                prev[a] = now;
            }
        }
        self.push(n, &s);
    }
}

/// The batch-means long-run covariance of the summed score (n_free × n_free) and the
/// batches it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchMeans {
    /// `B̂` in the optimiser's coordinates (module documentation).
    pub meat: DMatrix<f64>,
    /// Number of batches B (the t quantile takes B − 1 degrees of freedom).
    pub batches: usize,
    /// Mean samples in a batch (whole blocks of the pass; an experiment's last batch may be
    /// up to half as long again, or its only one shorter).
    pub batch_samples: usize,
    /// Batches of each experiment, in order: a parameter of one experiment alone (per-log,
    /// or its initial state) is seen by its experiment's batches only.
    pub per_experiment: Vec<usize>,
    /// For a problem kept by arrowhead blocks: `B̂` as an arrowhead matrix (the batches'
    /// uncentred products, each within its experiment's columns and the shared ones) and
    /// the rank-two centring term outside that structure; `meat` is then empty (0 × 0).
    pub(crate) arrow: Option<(Arrowhead, LowRank)>,
}

/// Every experiment's block scores in the optimiser's coordinates, in time order.
#[derive(Clone, Debug, Default)]
pub(crate) struct ScoreSeries {
    np: usize,
    /// Per experiment: the block counts and their n_free-long scores (or, kept by
    /// arrowhead blocks, their local columns' chained scores, length m).
    experiments: Vec<(Vec<usize>, Vec<DVector<f64>>)>,
    /// The arrowhead layout, and each experiment's local columns (in the optimiser's
    /// coordinates), when the scores are kept by local columns.
    local: Option<(Arc<ArrowLayout>, Vec<Vec<usize>>)>,
}

impl ScoreSeries {
    pub(crate) fn new(np: usize) -> Self {
        Self { np, experiments: Vec::new(), local: None }
    }

    /// Scores kept by each experiment's local columns (memory `O(blocks · m)`, not
    /// `O(blocks · n_free)`), for a problem of arrowhead `layout`.
    pub(crate) fn structured(layout: Arc<ArrowLayout>) -> Self {
        Self { np: layout.n(), experiments: Vec::new(), local: Some((layout, Vec::new())) }
    }

    /// Adds one experiment's block scores, chained by `map` into the optimiser's coordinates.
    pub(crate) fn add(&mut self, map: &LocalMap, blocks: &BlockScores) {
        let m = blocks.m;
        if let Some((_, globals)) = &mut self.local {
            let scores = blocks
                .values
                .chunks_exact(m.max(1))
                .take(blocks.counts.len())
                .map(|local| DVector::from_iterator(m, local.iter().zip(&map.dtheta).map(|(v, d)| d * v)))
                .collect();
            globals.push(map.global.clone());
            self.experiments.push((blocks.counts.clone(), scores));
            return;
        }
        let scores = blocks
            .values
            .chunks_exact(m.max(1))
            .take(blocks.counts.len())
            .map(|local| {
                let mut s = DVector::zeros(self.np);
                for (a, v) in local.iter().enumerate().take(m) {
                    s[map.global[a]] += map.dtheta[a] * v;
                }
                s
            })
            .collect();
        self.experiments.push((blocks.counts.clone(), scores));
    }

    /// Adds one experiment's block scores already in the optimiser's coordinates (m = n_free).
    pub(crate) fn add_plain(&mut self, blocks: &BlockScores) {
        let scores = blocks.values.chunks_exact(self.np.max(1)).map(DVector::from_column_slice).collect();
        self.experiments.push((blocks.counts.clone(), scores));
    }

    /// Adds one experiment's per-sample scores (n_free each), in time order, a block of
    /// `block` samples at a time.
    pub(crate) fn add_samples(&mut self, scores: &[DVector<f64>], block: usize) {
        let counts = scores.chunks(block).map(<[_]>::len).collect();
        let sums =
            scores.chunks(block).map(|c| c.iter().fold(DVector::zeros(self.np), |a, s| a + s)).collect();
        self.experiments.push((counts, sums));
    }

    /// Each experiment's block counts and block scores, in time order (scores in the
    /// optimiser's coordinates, length n_free; empty for scores kept by local columns).
    pub(crate) fn plain_blocks(&self) -> impl Iterator<Item = (&[usize], &[DVector<f64>])> {
        self.experiments
            .iter()
            .filter(|_| self.local.is_none())
            .map(|(counts, scores)| (counts.as_slice(), scores.as_slice()))
    }

    /// The sum of every recorded block score (length n_free): the total score.
    pub(crate) fn total(&self) -> DVector<f64> {
        match &self.local {
            None => self.experiments.iter().flat_map(|(_, s)| s).fold(DVector::zeros(self.np), |a, s| a + s),
            Some((_, globals)) => {
                let mut total = DVector::zeros(self.np);
                for ((_, scores), global) in self.experiments.iter().zip(globals) {
                    for s in scores {
                        for (&g, v) in global.iter().zip(s.iter()) {
                            total[g] += v;
                        }
                    }
                }
                total
            }
        }
    }

    /// The batch-means covariance over about `target` batches (module documentation);
    /// `None` when fewer than [`MIN_BATCHES`] batches can be formed, or when no experiment
    /// recorded its scores.
    pub(crate) fn batch_means(&self, target: usize) -> Option<BatchMeans> {
        let total: usize = self.experiments.iter().flat_map(|(c, _)| c).sum();
        if total == 0 || self.experiments.is_empty() {
            return None;
        }
        let groups = partition(self.experiments.iter().map(|(c, _)| c.as_slice()), total, target);
        let mut batches: Vec<(usize, DVector<f64>)> = Vec::with_capacity(groups.len());
        // Where each experiment's batches start, then the end.
        let mut cuts = Vec::with_capacity(self.experiments.len() + 1);
        for (e, (counts, scores)) in self.experiments.iter().enumerate() {
            cuts.push(batches.len());
            let dim = if self.local.is_some() { scores.first().map_or(0, DVector::len) } else { self.np };
            for g in groups.iter().filter(|g| g.experiment == e) {
                let n = counts[g.blocks.clone()].iter().chain(&counts[g.tail.clone()]).sum();
                batches.push((n, g.sum(scores, || DVector::zeros(dim))));
            }
        }
        cuts.push(batches.len());
        let b = batches.len();
        if b < MIN_BATCHES {
            return None;
        }
        let per_experiment: Vec<usize> = cuts.windows(2).map(|w| w[1] - w[0]).collect();
        if let Some((layout, globals)) = &self.local {
            let arrow = structured_meat(layout, globals, &per_experiment, &batches, total, self.np);
            let meat = DMatrix::zeros(0, 0);
            return Some(BatchMeans {
                meat,
                batches: b,
                batch_samples: total / b,
                per_experiment,
                arrow: Some(arrow),
            });
        }
        let sum = batches.iter().fold(DVector::zeros(self.np), |a, (_, s)| a + s);
        let mut meat = DMatrix::zeros(self.np, self.np);
        for (n, s) in &batches {
            let d = s - &sum * (*n as f64 / total as f64);
            meat += &d * d.transpose();
        }
        meat *= b as f64 / (b - 1) as f64;
        Some(BatchMeans { meat, batches: b, batch_samples: total / b, per_experiment, arrow: None })
    }
}

/// The batch-means meat of scores kept by local columns: with `S_b` the batch sums (each
/// in its experiment's columns `globals[e]`), `α_b = n_b/N` and `S = Σ_b S_b`,
/// `B̂ = B/(B − 1) Σ_b (S_b − α_b S)(S_b − α_b S)ᵀ = c [Σ_b S_b S_bᵀ − T Sᵀ − S Tᵀ + σ S Sᵀ]`
/// with `T = Σ_b α_b S_b`, `σ = Σ_b α_b²`: the first sum is of arrowhead structure, the
/// rest a rank-two term.
fn structured_meat(
    layout: &Arc<ArrowLayout>,
    globals: &[Vec<usize>],
    per_experiment: &[usize],
    batches: &[(usize, DVector<f64>)],
    total: usize,
    np: usize,
) -> (Arrowhead, LowRank) {
    let b = batches.len();
    let c = b as f64 / (b - 1) as f64;
    let mut arrow = Arrowhead::zeros(Arc::clone(layout));
    let (mut sum, mut t, mut sigma) = (DVector::zeros(np), DVector::zeros(np), 0.0);
    let owners = per_experiment.iter().enumerate().flat_map(|(e, &k)| std::iter::repeat_n(e, k));
    for ((n, s), e) in batches.iter().zip(owners) {
        let global = &globals[e];
        let alpha = *n as f64 / total as f64;
        sigma += alpha * alpha;
        for (x, (&g, &v)) in global.iter().zip(s.iter()).enumerate() {
            sum[g] += v;
            t[g] += alpha * v;
            for (&h, &w) in global.iter().zip(s.iter()).skip(x) {
                arrow.add_symmetric(g, h, c * v * w);
            }
        }
    }
    let low = vec![(-c, t.clone(), sum.clone()), (-c, sum.clone(), t), (c * sigma, sum.clone(), sum)];
    (arrow, low)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// AR(1) scores x_k = ρ x_{k−1} + e_k of one parameter: the batch-means variance of
    /// their sum approaches the long-run variance N σ²/(1 − ρ)², far above the white N σ²/(1 − ρ²).
    #[test]
    fn batch_means_recover_an_ar1_long_run_variance() {
        let (rho, n) = (0.9, 200_000usize);
        let mut rng = crate::estimate::test_rng::Xorshift::new(0x1234_5678_9abc_def1);
        let mut uniform = || rng.uniform();
        let mut x = 0.0;
        let scores: Vec<DVector<f64>> = (0..n)
            .map(|_| {
                // Sum of 12 uniforms − 6: unit variance.
                let e: f64 = (0..12).map(|_| uniform()).sum::<f64>() - 6.0;
                x = rho * x + e;
                DVector::from_element(1, x)
            })
            .collect();
        let mut series = ScoreSeries::new(1);
        series.add_samples(&scores, 256);
        let bm = series.batch_means(TARGET_BATCHES).expect("enough batches");
        // Batches of 24 blocks of 256 (6144 samples, the boundary nearest 6250): 32, and
        // the tail of 3392 samples a batch of its own.
        assert_eq!(bm.batches, 33);
        assert_eq!(bm.per_experiment, vec![33]);
        let long_run = n as f64 / (1.0 - rho) / (1.0 - rho);
        let ratio = bm.meat[(0, 0)] / long_run;
        // 31 degrees of freedom: the estimate's relative sd is √(2/31) = 0.25.
        assert!((0.5..1.6).contains(&ratio), "batch means / long-run variance = {ratio}");
        let white = n as f64 / (1.0 - rho * rho);
        assert!(bm.meat[(0, 0)] > 4.0 * white);
    }

    /// Experiments never share a batch; a short tail joins its experiment's last batch;
    /// too few batches give none.
    #[test]
    fn batches_stay_within_experiments() {
        let one = |n: usize| vec![DVector::from_element(2, 1.0); n];
        let mut series = ScoreSeries::new(2);
        series.add_samples(&one(1000), 100);
        series.add_samples(&one(1050), 100);
        let bm = series.batch_means(20).expect("batches");
        // length ⌈2050/20⌉ = 103: every block of 100 is a batch, the second experiment's
        // tail of 50 joins its last.
        assert_eq!(bm.batches, 20);
        assert_eq!(bm.per_experiment, vec![10, 10]);
        assert!(ScoreSeries::new(2).batch_means(20).is_none());
        let mut short = ScoreSeries::new(1);
        short.add_samples(&vec![DVector::from_element(1, 1.0); 700], 256);
        assert!(short.batch_means(TARGET_BATCHES).is_none());
    }
}
