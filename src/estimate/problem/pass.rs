//! One residual/sensitivity pass over an experiment: the single loop that the cost, the
//! normal equations, the statistics and the robust scale are sums over.
//!
//! The pass runs a block of samples at a time ([`crate::simulate::simulate_blocks`]) and
//! hands each block on as a [`Chunk`]: residuals, sample weights and the Jacobian in the
//! experiment's *local* columns (the sensitivities to its free model parameters and free
//! initial state, before the chain factor `dθ/dp`). Sums over a chunk are dot products over
//! contiguous arrays; they are mapped to the optimiser's coordinates once per experiment
//! ([`LocalMap`]).

use super::PemProblem;
use super::local::{Chunk, Cols, LocalMap, Pass, ResidualFilter, Source};
use crate::error::Result;
use crate::model::{BLOCK_LEN, GreyBoxModel};
use crate::simulate::{SimOptions, simulate_blocks};
use nalgebra::DVector;

/// Unit sample weights for an experiment without weights.
static ONES: [f64; BLOCK_LEN] = [1.0; BLOCK_LEN];

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// The local columns of experiment e at p (empty without the Jacobian).
    pub(crate) fn local_map(&self, e: usize, p: &DVector<f64>) -> LocalMap {
        let term = &self.terms[e];
        let (global, dtheta) = self.chain(e, p);
        let mut map = LocalMap::default();
        for (g, d) in global.into_iter().zip(dtheta) {
            if let Some(g) = g {
                map.global.push(g);
                map.dtheta.push(d);
            }
        }
        if let Some(g) = term.x0_free {
            for i in 0..term.prep.x0.len() {
                map.global.push(g + i);
                map.dtheta.push(self.free[g + i].transform.dtheta_dp(p[g + i]));
            }
        }
        map
    }

    /// Runs `f(chunk)` over the blocks of experiment e at p (see [`Chunk`]), with the
    /// local columns of [`local_map`](Self::local_map) when `mode.jacobian`; an error of
    /// `f` ends the pass there.
    ///
    /// # Errors
    /// Those of the simulation: invalid θ, [`crate::Error::SimulationDiverged`]; `f`'s.
    pub(crate) fn pass_blocks<F>(&self, e: usize, p: &DVector<f64>, mode: Pass, mut f: F) -> Result<LocalMap>
    where
        F: FnMut(&Chunk<'_>) -> Result<()>,
    {
        let term = &self.terms[e];
        let ny = self.model.n_outputs();
        let theta = self.theta(e, p);
        let map = if mode.jacobian { self.local_map(e, p) } else { LocalMap::default() };
        let x0 = self.x0(e, p);
        // Local column c reads sensitivity channel `sources[c]` of the block: θ_j, or x₀_m.
        let (global, _) = self.chain(e, p);
        let sources: Vec<Source> = if mode.jacobian {
            (0..theta.len())
                .filter(|&j| global[j].is_some())
                .map(Source::Theta)
                .chain(term.x0_free.iter().flat_map(|_| (0..x0.len()).map(Source::X0)))
                .collect()
        } else {
            Vec::new()
        };
        let m = sources.len();
        let first = self.first_sample(e);
        let mut eps = vec![0.0; ny * BLOCK_LEN];
        let mut owned = Vec::new();
        let mut filter =
            self.prefilters.get(e).filter(|_| mode.filtered).map(|l| ResidualFilter::new(l, ny, m));
        if filter.is_some() {
            owned = vec![0.0; ny * m * BLOCK_LEN];
        }
        let scale = if mode.jacobian { self.fd_scale(e, p) } else { Vec::new() };
        let options = SimOptions {
            horizon: self.horizon,
            x0: Some(&x0),
            x0_sensitivity: mode.jacobian && term.x0_free.is_some(),
            fd_scale: mode.jacobian.then_some(&scale[..]),
        };
        let y = &term.prep.y;
        simulate_blocks(self.model, &term.prep, &theta, &options, mode.jacobian, |b| {
            let (k0, len) = (b.k0, b.len);
            let lo = first.saturating_sub(k0).min(len);
            for (i, (e, col)) in eps.chunks_exact_mut(BLOCK_LEN).zip(y).enumerate() {
                let measured = &col[k0 + lo..k0 + len];
                for ((e, m), s) in e[lo..len].iter_mut().zip(measured).zip(&b.y(i)[lo..]) {
                    *e = m - s;
                }
            }
            let beta = match &term.weights {
                Some(w) => &w[k0 + lo..k0 + len],
                None => &ONES[lo..len],
            };
            let cols = match filter.as_mut() {
                Some(l) => {
                    for i in 0..ny {
                        for (c, src) in sources.iter().enumerate() {
                            let from = match *src {
                                Source::Theta(j) => b.dy(i, j),
                                Source::X0(mm) => b.dy0(i, mm),
                            };
                            let ch = (i * m + c) * BLOCK_LEN;
                            owned[ch + lo..ch + len].copy_from_slice(&from[lo..]);
                        }
                    }
                    l.apply_block(&mut eps, &mut owned, lo, len);
                    Cols::Owned(&owned)
                }
                None => Cols::Block(b, &sources),
            };
            f(&Chunk { k0, lo, len, m, eps: &eps, beta, cols })
        })?;
        Ok(map)
    }

    /// Runs `f(k, ε_k, w_k, J_k)` over every counted sample of experiment e
    /// ([`first_sample`](Self::first_sample) on), where `ε_k = y_k − ŷ_k` (length n_y),
    /// `w_k[i] = β_k Λ_i` and `J_k = ∂ŷ_k/∂p` is row-major `n_y × n_free` (empty without
    /// `mode.jacobian`): the per-sample view of [`pass_blocks`](Self::pass_blocks).
    ///
    /// # Errors
    /// As [`pass_blocks`](Self::pass_blocks).
    pub(crate) fn pass<F>(&self, e: usize, p: &DVector<f64>, mode: Pass, mut f: F) -> Result<()>
    where
        F: FnMut(usize, &[f64], &[f64], &[f64]),
    {
        let ny = self.model.n_outputs();
        let np = if mode.jacobian { self.free.len() } else { 0 };
        let map = if mode.jacobian { self.local_map(e, p) } else { LocalMap::default() };
        let (mut eps, mut w, mut jac) = (vec![0.0; ny], vec![0.0; ny], vec![0.0; ny * np]);
        self.pass_blocks(e, p, mode, |ch| {
            for t in 0..ch.len - ch.lo {
                for i in 0..ny {
                    eps[i] = ch.eps(i)[t];
                    w[i] = ch.beta()[t] * self.output_weights[i];
                    for (c, (&g, &d)) in map.global.iter().zip(&map.dtheta).enumerate() {
                        jac[i * np + g] = ch.col(i, c)[t] * d;
                    }
                }
                f(ch.k0 + ch.lo + t, &eps, &w, &jac);
            }
            Ok(())
        })?;
        Ok(())
    }
}

impl<M: GreyBoxModel> PemProblem<'_, M> {
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
