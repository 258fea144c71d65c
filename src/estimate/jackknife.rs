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

/// The deleted-batch shifts `θ̂₋g − θ̂ = −(M − M_g)⁻¹ (S − S_g)` (module documentation), one
/// per batch of `batches` ([`BlockSums::batches`]), each of length n_θ, at the estimate
/// whose sums are `m` (`M`, n_θ × n_θ) and `score` (`S`, n_θ); `None` when `M − M_g` is
/// singular for a batch (a batch that alone determines a parameter).
pub(crate) fn jackknife_shifts(
    m: &DMatrix<f64>,
    score: &DVector<f64>,
    batches: &[BatchSums],
) -> Option<Vec<DVector<f64>>> {
    let mut shifts = Vec::with_capacity(batches.len());
    for b in batches {
        let step = (m - &b.m).lu().solve(&(score - &b.score))?;
        if !step.iter().all(|v| v.is_finite()) {
            return None;
        }
        shifts.push(-step);
    }
    Some(shifts)
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
    let shifts = jackknife_shifts(m, score, batches)?;
    let mean = shifts.iter().fold(DVector::zeros(nth), |a, d| a + d) / g as f64;
    let mut v = DMatrix::zeros(nth, nth);
    for d in &shifts {
        let c = d - &mean;
        v += &c * c.transpose();
    }
    Some(v * ((g - 1) as f64 / g as f64))
}

/// Per parameter, the effective degrees of freedom of the jackknife variance
/// ([`jackknife_covariance`]) over `batches`, at the estimate whose `M = Σ Zᵀ D` is `m`
/// (n_θ × n_θ): Bell & McCaffrey's Satterthwaite approximation (*Survey Methodology* 28
/// (2002) 169–181; Imbens & Kolesár, *Rev. Econ. Stat.* 98 (2016) 701–712, recommend it
/// for few or unbalanced clusters) under the working model of independent equation errors
/// of one variance σ². Parameter j's deleted-batch shifts `d_g = a_gᵀ S_g`, with
/// `a_g = (M − M_g)⁻ᵀ e_j`, then have the covariance
/// `Σ_gh/σ² = δ_gh a_gᵀ M_g a_g − a_gᵀ M_g M⁻¹ M_h a_h` (exact for least squares, where
/// `M_g = X_gᵀX_g` and the residuals are `(I − H)ε`; on the diagonal
/// `[(M − M_g)⁻¹]_jj − [M⁻¹]_jj`, the growth of the parameter's variance when the batch
/// is deleted; for instrumental variables the instruments are taken to track the
/// regressors, `Z_gᵀZ_g ≈ M_g`), and the variance `Σ_g (d_g − d̄)² = dᵀCd`,
/// `C = I − 11ᵀ/G`, has `ν_j = tr(CΣ)²/tr(CΣCΣ)` degrees of freedom, in `[1, G − 1]`:
/// `G − 1` when every batch carries the parameter alike, `K − 1` when K batches carry it
/// alike (a drive cycle's transients, the low-speed samples that tell R_s), 1 where it is
/// not finite. Without this the intervals took t with `G − 1` degrees of freedom for every
/// parameter and were too narrow for one that a few batches carry. Where one batch
/// dominates, the jackknife's variance itself is biased up (its intervals over-cover).
/// `None` when `M` or some `M − M_g` is singular, or there are fewer than two batches.
/// Length n_θ.
pub(crate) fn effective_dof(m: &DMatrix<f64>, batches: &[BatchSums]) -> Option<Vec<f64>> {
    let (g, nth) = (batches.len(), m.nrows());
    if g < 2 {
        return None;
    }
    let m_inv = m.clone().try_inverse()?;
    let without: Option<Vec<DMatrix<f64>>> = batches.iter().map(|b| (m - &b.m).try_inverse()).collect();
    let without = without?;
    let most = (g - 1) as f64;
    let nu = (0..nth).map(|j| {
        // a_g, M_gᵀ a_g and M⁻¹ M_g a_g per batch.
        let a: Vec<DVector<f64>> = without.iter().map(|w| w.row(j).transpose()).collect();
        let left: Vec<DVector<f64>> = batches.iter().zip(&a).map(|(b, a)| b.m.transpose() * a).collect();
        let right: Vec<DVector<f64>> = batches.iter().zip(&a).map(|(b, a)| &m_inv * (&b.m * a)).collect();
        let mut sigma = DMatrix::from_fn(g, g, |p, q| -left[p].dot(&right[q]));
        for (p, b) in batches.iter().enumerate() {
            sigma[(p, p)] += a[p].dot(&(&b.m * &a[p]));
        }
        let centre = DMatrix::from_fn(g, g, |p, q| f64::from(u8::from(p == q)) - 1.0 / g as f64);
        let cs = &centre * &sigma;
        let nu = cs.trace().powi(2) / (&cs * &cs).trace();
        if nu.is_finite() { nu.clamp(1.0, most) } else { 1.0 }
    });
    Some(nu.collect())
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

    /// Equal batches give `G − 1` degrees of freedom; a parameter that K of 16 batches carry
    /// alike gets K − 1 (Bell & McCaffrey's exact value for that design), one that a single
    /// batch of eight carries almost alone about one.
    #[test]
    fn effective_dof_counts_the_batches_that_carry_a_parameter() {
        let batch = |a: f64, b: f64| BatchSums {
            samples: 10,
            score: DVector::zeros(2),
            m: DMatrix::from_row_slice(2, 2, &[a, 0.0, 0.0, b]),
        };
        let sum = |b: &[BatchSums]| b.iter().fold(DMatrix::zeros(2, 2), |a, b| a + &b.m);
        for k in [2, 3, 4, 8] {
            let carried: Vec<BatchSums> =
                (0..16).map(|g| batch(1.0, if g < k { 1.0 } else { 0.0 })).collect();
            let nu = effective_dof(&sum(&carried), &carried).unwrap();
            approx::assert_relative_eq!(nu[0], 15.0, max_relative = 1e-9);
            approx::assert_relative_eq!(nu[1], (k - 1) as f64, max_relative = 1e-9);
        }
        let mut batches: Vec<BatchSums> = (0..8).map(|_| batch(1.0, 1.0)).collect();
        batches[0] = batch(1.0, 1000.0);
        let m = sum(&batches);
        let nu = effective_dof(&m, &batches).unwrap();
        approx::assert_relative_eq!(nu[0], 7.0, max_relative = 1e-12);
        assert!((1.0..1.1).contains(&nu[1]), "{nu:?}");
        assert!(effective_dof(&m, &batches[..1]).is_none());
        // Between whole degrees of freedom, t interpolated in 1/ν (1/2.4 halfway between 1/2
        // and 1/3); clamped to [1, dof].
        let u = |nu: Vec<f64>| crate::estimate::Uncertainty {
            effective_dof: nu,
            ..crate::estimate::Uncertainty::choose(&[], 100, 7, None)
        };
        let t = crate::estimate::t_quantile_975;
        let half = u(vec![2.4]).t_quantile_of(0);
        approx::assert_relative_eq!(half, (t(2) * t(3)).sqrt(), max_relative = 1e-12);
        // scipy.stats.t.ppf(0.975, 1.5) = 6.0166: ln t interpolated within 3 %.
        approx::assert_relative_eq!(u(vec![1.5]).t_quantile_of(0), 6.0166, max_relative = 0.03);
        assert!(u(vec![f64::NAN]).t_quantile_of(0) == t(1));
        let none = crate::estimate::Uncertainty { effective_dof: vec![3.0], ..u(vec![]) };
        assert!(crate::estimate::Uncertainty { dof: 0, ..none }.t_quantile_of(0).is_infinite());
        assert_eq!(u(vec![0.2, 50.0]).t_quantile_of(0), t(1));
        assert_eq!(u(vec![0.2, 50.0]).t_quantile_of(1), t(7));
        assert_eq!(u(vec![4.0]).t_quantile_of(1), t(7));
    }

    /// Monte Carlo of the claim: `y = a + b x + e`, e white N(0, 1), 32 batches of 20
    /// samples with `x` non-zero in 4 of them (b carried by 4 batches, ν = 3). The
    /// jackknife's `± t·se` for b at G − 1 = 31 degrees of freedom covers 0.91; at the
    /// effective degrees of freedom ([`crate::estimate::Uncertainty::t_quantile_of`]), 0.97
    /// (400 seeded fits; the jackknife's variance is biased up by a few batches' leverage).
    #[test]
    fn effective_dof_restore_the_coverage_of_a_parameter_few_batches_carry() {
        let (n, len, reps) = (640, 20, 400);
        let x: Vec<f64> = (0..n)
            .map(|k| if (k / len) % 8 == 3 { (k % len) as f64 / len as f64 - 0.5 } else { 0.0 })
            .collect();
        let mut rng = crate::estimate::test_rng::Xorshift::new(0x9e37_79b9_7f4a_7c15);
        let mut normal = move || {
            let (u, v) = (rng.uniform().max(1e-300), rng.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let (mut fixed, mut effective, mut nu_sum) = (0, 0, 0.0);
        let white = crate::estimate::Uncertainty::choose(&[], n, 31, None);
        for _ in 0..reps {
            let y: Vec<f64> = x.iter().map(|&xk| 1.0 + 2.0 * xk + normal()).collect();
            let (mut m, mut r) = (DMatrix::zeros(2, 2), DVector::zeros(2));
            for k in 0..n {
                let v = DVector::from_row_slice(&[1.0, x[k]]);
                m += &v * v.transpose();
                r += &v * y[k];
            }
            let theta = m.clone().lu().solve(&r).unwrap();
            let batches: Vec<BatchSums> = (0..n / len)
                .map(|g| {
                    let (mut mg, mut sg) = (DMatrix::zeros(2, 2), DVector::zeros(2));
                    for k in g * len..(g + 1) * len {
                        let v = DVector::from_row_slice(&[1.0, x[k]]);
                        mg += &v * v.transpose();
                        sg += &v * -(y[k] - v.dot(&theta));
                    }
                    BatchSums { samples: len, score: sg, m: mg }
                })
                .collect();
            let s = batches.iter().fold(DVector::zeros(2), |a, b| a + &b.score);
            let se = jackknife_covariance(&m, &s, &batches).unwrap()[(1, 1)].sqrt();
            let nu = effective_dof(&m, &batches).unwrap()[1];
            nu_sum += nu;
            let err = (theta[1] - 2.0).abs();
            fixed += usize::from(err <= crate::estimate::t_quantile_975(31) * se);
            let u = crate::estimate::Uncertainty { effective_dof: vec![0.0, nu], ..white.clone() };
            effective += usize::from(err <= u.t_quantile_of(1) * se);
        }
        let (fixed, effective) = (fixed as f64 / reps as f64, effective as f64 / reps as f64);
        approx::assert_relative_eq!(nu_sum / reps as f64, 3.0, max_relative = 0.01);
        assert!(fixed < 0.92, "t(31) covers {fixed}");
        assert!((0.93..=0.98).contains(&effective), "t(ν) covers {effective} (t(31): {fixed})");
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
