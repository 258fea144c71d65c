//! Instrumental variables for an equation error `ε_k(θ)` (n_y per sample) whose regressors
//! carry noise: the estimating equations `Σ_k Z_kᵀ ε_k(θ) = 0` with instruments `Z_k`
//! (n_y × n_θ) correlated with the Jacobian `D_k = ∂ε_k/∂θ` but not with `ε_k`, solved by
//! Newton steps `δ = −(Σ Zᵀ D)⁻¹ Σ Zᵀ ε`, and the estimate's covariance
//! `M⁻¹ Ω M⁻ᵀ` with `M = Σ_k Z_kᵀ D_k` and `Ω` the variance of the summed score
//! `Σ_k Z_kᵀ ε_k`: `Σ_i σ̂_i² Σ_k Z_kiᵀ Z_ki` for white equation errors; otherwise the
//! delete-one-batch jackknife over the batch means' batches ([`super::jackknife`]), or the
//! batch means of the score (`problem::batches`) where a batch alone determines a
//! parameter (Söderström & Stoica, *System Identification*,
//! 1989, 8.2–8.3; Söderström, *Automatica* 43 (2007) 939–958, errors in variables; Young,
//! *Recursive Estimation and Time-Series Analysis*, 2nd ed., 2011, ch. 7, refined IV).
//!
//! The instruments are the caller's (for a simulation model, the Jacobian evaluated on the
//! noise-free outputs an auxiliary model simulates); this module sums, steps and gives the
//! covariance, for any model.

use super::jackknife::{BlockSums, effective_dof, jackknife_covariance, jackknife_shifts};
use super::problem::LagStream;
use super::problem::{BlockScores, LagSums, ScoreSeries, TARGET_BATCHES, WHITENESS_LAGS};
use super::quantile::t_quantile_975;
use super::restricted::restricted_offsets;
use super::result::Uncertainty;
use crate::error::{Error, Result};
use crate::estimate::metrics::{self, Whiteness};
use crate::model::{GreyBoxModel, Prepared};
use crate::simulate::{SimOptions, simulate};
use nalgebra::{DMatrix, DVector};

/// Running sums of the IV estimating equations over one or more experiments.
#[derive(Clone, Debug)]
pub struct IvSums {
    ny: usize,
    nth: usize,
    /// `M = Σ_k Z_kᵀ D_k` (n_θ × n_θ).
    pub zd: DMatrix<f64>,
    /// `Σ_k Z_kᵀ ε_k` (n_θ).
    pub score: DVector<f64>,
    /// Per output i: `Σ_k Z_kiᵀ Z_ki` (n_θ × n_θ).
    zz: Vec<DMatrix<f64>>,
    /// Per output: `Σ_k ε_ki²`.
    pub sse: Vec<f64>,
    /// Samples summed.
    pub count: usize,
    lags: Vec<Vec<LagSums>>,
    streams: Vec<LagStream>,
    scores: ScoreSeries,
    /// The current experiment's score `Zᵀε` summed per block.
    blocks: BlockScores,
    /// One sample's score (scratch).
    sample: Vec<f64>,
    /// Samples per block of the batch means.
    block: usize,
    /// The blocks' sums for the jackknife.
    jack: BlockSums,
}

/// The covariance of an IV estimate and how it was formed.
#[derive(Clone, Debug)]
pub struct IvCovariance {
    /// The covariance of the standard errors (n_θ × n_θ): the jackknife's, the batch means'
    /// or the white one ([`Uncertainty`] says which).
    pub cov: DMatrix<f64>,
    /// The white-noise covariance `M⁻¹ (Σ_i σ̂_i² Z_iᵀZ_i) M⁻ᵀ` (n_θ × n_θ).
    pub cov_white: DMatrix<f64>,
    /// Which, its degrees of freedom and the whiteness test that chose.
    pub uncertainty: Uncertainty,
    /// Whiteness of each output's equation error.
    pub whiteness: Vec<Whiteness>,
    /// Per parameter, the 95 % interval's ends less the estimate, `[lo, hi]` (`lo ≤ 0 ≤ hi`,
    /// the parameter's unit): where the equation errors are coloured and batches are
    /// formed, the restricted interval (`estimate::restricted`; asymmetric where the
    /// batches carry the parameter unevenly); otherwise, and for a parameter whose
    /// restricted set is unbounded, `± t·√cov_jj`. Length n_θ.
    pub ci95_offsets: Vec<[f64; 2]>,
    /// The parameters (indices) whose restricted set was unbounded (too few batches carry
    /// them) and whose interval is therefore `± t·√cov_jj`; empty otherwise.
    pub unbounded: Vec<usize>,
}

impl IvSums {
    /// Empty sums for `ny` equation errors per sample and `nth` parameters (shapes of
    /// [`add`](Self::add)).
    pub fn new(ny: usize, nth: usize) -> Self {
        Self::with_block_len(ny, nth, crate::model::BLOCK_LEN)
    }

    /// Empty sums as [`new`](Self::new), the score kept in blocks of `block` samples (at
    /// least 1) for the batch means: short blocks for a short record, whose batches would
    /// otherwise be too few (fewer than 8 batches of whole blocks: the white covariance).
    pub fn with_block_len(ny: usize, nth: usize, block: usize) -> Self {
        Self {
            ny,
            nth,
            zd: DMatrix::zeros(nth, nth),
            score: DVector::zeros(nth),
            zz: vec![DMatrix::zeros(nth, nth); ny],
            sse: vec![0.0; ny],
            count: 0,
            lags: vec![Vec::new(); ny],
            streams: Vec::new(),
            scores: ScoreSeries::new(nth),
            blocks: BlockScores::with_len(nth, block),
            sample: vec![0.0; nth],
            block: block.max(1),
            jack: BlockSums::new(nth, block),
        }
    }

    /// Starts an experiment: lags and batches never reach across experiments (call before
    /// its first [`add`](Self::add)).
    pub fn start_experiment(&mut self) {
        self.streams = (0..self.ny).map(|_| LagStream::new(WHITENESS_LAGS)).collect();
        self.blocks = BlockScores::with_len(self.nth, self.block);
        self.jack.start_experiment();
    }

    /// Adds sample k: equation error `eps` (n_y, the outputs' units), its Jacobian `d` and
    /// instruments `z` (row-major n_y × n_θ each, output unit per parameter unit).
    ///
    /// # Panics
    /// If `eps` is shorter than n_y or `d`, `z` shorter than n_y n_θ (a caller's bug, not
    /// user input).
    pub fn add(&mut self, eps: &[f64], d: &[f64], z: &[f64]) {
        let nth = self.nth;
        let s = &mut self.sample;
        s.fill(0.0);
        // Column-major n_θ × n_θ sums, a column (fixed b) at a time; every element takes
        // the same terms in the same order as indexed access would.
        let zd = self.zd.as_mut_slice();
        let open = self.jack.open_m_mut().as_mut_slice();
        for i in 0..self.ny {
            let (zi, di) = (&z[i * nth..(i + 1) * nth], &d[i * nth..(i + 1) * nth]);
            for (a, v) in s.iter_mut().enumerate() {
                *v += zi[a] * eps[i];
            }
            let zz = self.zz[i].as_mut_slice();
            let column = nth.max(1);
            for (b, ((zd_b, open_b), zz_b)) in zd
                .chunks_exact_mut(column)
                .zip(open.chunks_exact_mut(column))
                .zip(zz.chunks_exact_mut(column))
                .enumerate()
            {
                let (d_b, z_b) = (di[b], zi[b]);
                for (a, &z_a) in zi.iter().enumerate() {
                    let p = z_a * d_b;
                    zd_b[a] += p;
                    open_b[a] += p;
                    zz_b[a] += z_a * z_b;
                }
            }
            self.sse[i] += eps[i] * eps[i];
            if let Some(st) = self.streams.get_mut(i) {
                st.push(&[eps[i]]);
            }
        }
        for (total, v) in self.score.iter_mut().zip(&self.sample) {
            *total += v;
        }
        self.blocks.add(&self.sample);
        self.jack.count();
        self.count += 1;
    }

    /// Ends the current experiment (after its last [`add`](Self::add)).
    pub fn end_experiment(&mut self) {
        for (all, st) in self.lags.iter_mut().zip(std::mem::take(&mut self.streams)) {
            all.push(st.finish());
        }
        self.blocks.close();
        self.jack.close();
        self.scores.add_plain(&self.blocks);
    }

    /// The Newton step `δ = −M⁻¹ Σ Zᵀε` \[parameter units\] (n_θ).
    ///
    /// # Errors
    /// [`Error::Numerical`] when `M` is singular (instruments that do not see a parameter).
    pub fn step(&self) -> Result<DVector<f64>> {
        let lu = self.zd.clone().lu();
        lu.solve(&(-&self.score)).filter(|d| d.iter().all(|v| v.is_finite())).ok_or_else(|| {
            Error::Numerical {
                context: "instrumental variables".into(),
                reason: "Σ ZᵀD is singular: the instruments do not determine every parameter".into(),
            }
        })
    }

    /// The deleted-batch shifts of the estimate whose sums these are, one per batch of the
    /// jackknife ([`super::jackknife::jackknife_shifts`]; \[parameter units\], n_θ each),
    /// whether or not its covariance takes them; for a paired comparison with another
    /// estimate from the same data ([`super::paired_difference_variance`]).
    /// `None` where the batches cannot be formed or a batch alone determines a parameter.
    pub(crate) fn jackknife_shifts(&self) -> Option<Vec<DVector<f64>>> {
        let batches = self.jack.batches(&self.scores, TARGET_BATCHES)?;
        jackknife_shifts(&self.zd, &self.score, &batches)
    }

    /// The estimate's covariance at the point the sums were taken: batch means when the
    /// equation errors fail the whiteness test (and batches can be formed), white otherwise.
    ///
    /// # Errors
    /// [`Error::Numerical`] when `M` is singular.
    pub fn covariance(&self) -> Result<IvCovariance> {
        let m_inv = self.zd.clone().try_inverse().ok_or_else(|| Error::Numerical {
            context: "instrumental variables".into(),
            reason: "Σ ZᵀD is singular: no covariance".into(),
        })?;
        let n = self.count;
        let dof = (n * self.ny).saturating_sub(self.nth);
        let whiteness: Vec<Whiteness> = self.lags.iter().map(|s| metrics::whiteness_of(s)).collect();
        let mut omega = DMatrix::zeros(self.nth, self.nth);
        for (i, zz) in self.zz.iter().enumerate() {
            let sigma2 = self.sse[i] / (n as f64 - self.nth as f64 / self.ny as f64).max(1.0);
            omega += zz * sigma2;
        }
        let sandwich = |o: &DMatrix<f64>| &m_inv * o * m_inv.transpose();
        let cov_white = sandwich(&omega);
        let offered = self.scores.batch_means(TARGET_BATCHES);
        let mut uncertainty = Uncertainty::choose(&whiteness, n, dof, offered.as_ref());
        let bm = uncertainty.taken(offered.as_ref());
        // The batches' jackknife where batch means are taken (and it exists: no batch alone
        // determines a parameter); their sandwich otherwise.
        let batches = bm.and_then(|_| self.jack.batches(&self.scores, TARGET_BATCHES));
        let jackknife = batches.as_deref().and_then(|b| jackknife_covariance(&self.zd, &self.score, b));
        uncertainty.jackknife = jackknife.is_some();
        if uncertainty.jackknife {
            uncertainty.effective_dof =
                batches.as_deref().and_then(|b| effective_dof(&self.zd, b)).unwrap_or_default();
        }
        let cov = match jackknife {
            Some(v) => v,
            None => bm.map_or_else(|| cov_white.clone(), |b| sandwich(&b.meat)),
        };
        // The intervals: restricted where the batches give them (at the batches' t: the
        // restriction widens them where the batches carry a parameter unevenly), else ± t·se
        // at the parameter's own degrees of freedom.
        let tq = t_quantile_975(uncertainty.dof);
        let restricted = batches
            .as_deref()
            .and_then(|b| restricted_offsets(&self.zd, &self.score, b, tq))
            .unwrap_or_default();
        uncertainty.restricted = restricted.iter().any(Option::is_some);
        let unbounded =
            (0..self.nth).filter(|&j| uncertainty.restricted && restricted[j].is_none()).collect();
        let ci95_offsets = (0..self.nth)
            .map(|j| {
                restricted.get(j).copied().flatten().unwrap_or_else(|| {
                    let half = uncertainty.t_quantile_of(j) * cov[(j, j)].max(0.0).sqrt();
                    [-half, half]
                })
            })
            .collect();
        Ok(IvCovariance { cov, cov_white, uncertainty, whiteness, ci95_offsets, unbounded })
    }
}

/// The IV sums at θ of the one-step equation error of a model whose state is its output
/// (`n_x = n_y`, the output the state): `ε_k = y[k+1] − x⁺(θ, k, y[k])`, the step from the
/// measured state; `D_k = −∂x⁺/∂θ` there; instruments `Z_k = −∂x⁺/∂θ` of interval `k − 1`
/// from the state the model simulates at θ from the first sample (output error: noise-free
/// up to the inputs' noise), so that neither the measured state's noise (in `ε_k` as
/// `y[k+1]`'s and `y[k]`'s) nor the input of interval k (in `ε_k` through the step) reaches
/// them (Söderström & Stoica, *System Identification*, 1989, 8.2: instruments from an
/// auxiliary model's simulated outputs and delayed inputs). Summed over `preps`, one
/// experiment each.
///
/// # Errors
/// [`Error::InvalidOption`] for a model without analytic sensitivities or whose state is
/// not its output; those of [`crate::simulate::simulate`].
pub fn one_step_sums<M: GreyBoxModel>(
    model: &M,
    preps: &[Prepared<M::Inputs>],
    theta: &[f64],
) -> Result<IvSums> {
    let (nx, nth) = (model.n_states(), theta.len());
    let sens = model.sensitivities().ok_or_else(|| Error::InvalidOption {
        option: "method".into(),
        reason: format!(
            "instrumental variables need the analytic sensitivities `{}` does not have",
            model.name()
        ),
    })?;
    if nx != model.n_outputs() || nx == 0 {
        return Err(Error::InvalidOption {
            option: "method".into(),
            reason: format!(
                "instrumental variables on the one-step error need a state that is the output (`{}`)",
                model.name()
            ),
        });
    }
    let mut acc = IvSums::new(nx, nth);
    let zero = vec![0.0; nx * nth];
    let (mut x, mut x_sim, mut next, mut d, mut z, mut z_prev) = (
        vec![0.0; nx],
        vec![0.0; nx],
        vec![0.0; nx],
        vec![0.0; nx * nth],
        vec![0.0; nx * nth],
        vec![0.0; nx * nth],
    );
    let mut scratch = vec![0.0; nx];
    for prep in preps {
        let c = model.coefficients(theta, &prep.inputs)?;
        let sim = simulate(model, prep, theta, &SimOptions::default())?;
        acc.start_experiment();
        for k in 0..prep.n.saturating_sub(1) {
            prep.y_at(k, &mut x);
            x_sim.copy_from_slice(&sim[k * nx..(k + 1) * nx]);
            sens.step_sensitivity(&c, &prep.inputs, k, &x, &zero, &mut next, &mut d);
            sens.step_sensitivity(&c, &prep.inputs, k, &x_sim, &zero, &mut scratch, &mut z);
            if k > 0 {
                // ε, −∂x⁺/∂θ and the instruments' sign, in place (each buffer is refilled
                // before it is read again).
                prep.y_at(k + 1, &mut scratch);
                for (y, p) in scratch.iter_mut().zip(&next) {
                    *y -= p;
                }
                d.iter_mut().chain(z_prev.iter_mut()).for_each(|v| *v = -*v);
                acc.add(&scratch, &d, &z_prev);
            }
            std::mem::swap(&mut z, &mut z_prev);
        }
        acc.end_experiment();
    }
    Ok(acc)
}

impl IvCovariance {
    /// The 0.975 quantile of Student's t at [`Uncertainty::dof`]: the factor of the 95 %
    /// intervals `± t·√cov_jj`, and the quantile of the restricted ones.
    pub fn t_quantile(&self) -> f64 {
        t_quantile_975(self.uncertainty.dof)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regression y = θ x + e with x observed with noise: least squares is biased toward
    /// zero, IV with the previous noise-free-correlated regressor as instrument is not, and
    /// its interval covers the truth.
    #[test]
    fn iv_removes_the_attenuation_of_a_noisy_regressor() {
        let mut rng = crate::estimate::test_rng::Xorshift::new(0x9e37_79b9_7f4a_7c15);
        let mut normal = || {
            let mut s = 0.0;
            for _ in 0..12 {
                s += rng.uniform();
            }
            s - 6.0
        };
        let (theta, n) = (2.0, 50_000);
        let truth: Vec<f64> = (0..n).map(|k| (k as f64 * 0.01).sin() * 3.0).collect();
        let x: Vec<f64> = truth.iter().map(|t| t + 0.5 * normal()).collect();
        let y: Vec<f64> = truth.iter().map(|t| theta * t + 0.1 * normal()).collect();
        let mut est = 0.0;
        for _ in 0..3 {
            let mut sums = IvSums::new(1, 1);
            sums.start_experiment();
            for k in 1..n {
                // ε = y − θ x, D = −x, instrument z = −x[k−1] (its noise independent of ε_k).
                sums.add(&[y[k] - est * x[k]], &[-x[k]], &[-x[k - 1]]);
            }
            sums.end_experiment();
            est += sums.step().unwrap()[0];
        }
        let mut sums = IvSums::new(1, 1);
        sums.start_experiment();
        for k in 1..n {
            sums.add(&[y[k] - est * x[k]], &[-x[k]], &[-x[k - 1]]);
        }
        sums.end_experiment();
        let cov = sums.covariance().unwrap();
        let se = cov.cov[(0, 0)].sqrt();
        let ls = x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>() / x.iter().map(|a| a * a).sum::<f64>();
        assert!((ls - theta).abs() > 0.03, "least squares {ls} should be attenuated");
        assert!((est - theta).abs() < cov.t_quantile() * se, "IV {est} ± {se}");
    }
}
