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
use crate::error::Result;
use crate::estimate::filter::Butterworth;
use crate::model::{BLOCK_LEN, Block, GreyBoxModel};
use crate::simulate::{SimOptions, simulate_blocks};
use nalgebra::DVector;

/// What a pass computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Pass {
    /// Also the Jacobian `J_k = ∂ŷ_k/∂p` (forward sensitivities); otherwise `J_k` is empty.
    pub jacobian: bool,
    /// Run the residual prefilter L(q) over ε (and J), when the problem has one.
    pub filtered: bool,
}

impl Pass {
    /// Residuals and Jacobian as the criterion sees them.
    pub const CRITERION: Self = Self { jacobian: true, filtered: true };
    /// Residuals only, as the criterion sees them.
    pub const COST: Self = Self { jacobian: false, filtered: true };
    /// Raw residuals and Jacobian (no prefilter).
    pub const RAW: Self = Self { jacobian: true, filtered: false };
    /// Raw residuals only.
    pub const RAW_RESIDUALS: Self = Self { jacobian: false, filtered: false };
}

/// The local columns of one experiment: column c is the free parameter `global[c]` of the
/// optimiser with chain factor `dtheta[c]` (`∂ŷ/∂p_g = dθ/dp · local column`).
#[derive(Clone, Debug, Default)]
pub(crate) struct LocalMap {
    /// Index of each local column in the optimiser's vector p.
    pub global: Vec<usize>,
    /// `dθ/dp` (or `dx₀/dp`) of each local column.
    pub dtheta: Vec<f64>,
}

impl LocalMap {
    /// Number of local columns m.
    pub fn len(&self) -> usize {
        self.global.len()
    }
}

/// One block of a pass: samples `k0 + lo .. k0 + len` count (the samples before `lo`
/// precede the experiment's first counted sample). Each accessor gives the counted
/// samples: `eps(i)` the residual `ε_i = y_i − ŷ_i` (prefiltered when the pass is),
/// `col(i, c)` the local Jacobian column c of output i (prefiltered likewise; none without
/// the Jacobian), `beta()` the sample weights β_k.
pub(crate) struct Chunk<'a> {
    pub k0: usize,
    pub lo: usize,
    pub len: usize,
    pub m: usize,
    eps: &'a [f64],
    beta: &'a [f64],
    cols: Cols<'a>,
}

/// Where a chunk's Jacobian columns are: copied (and prefiltered), or in the block.
enum Cols<'a> {
    /// Channel `i m + c` of [`BLOCK_LEN`] each.
    Owned(&'a [f64]),
    /// The block's sensitivity channels, local column c from `sources[c]`.
    Block(&'a Block, &'a [Source]),
}

impl Chunk<'_> {
    /// The counted residuals of output i.
    #[inline]
    pub fn eps(&self, i: usize) -> &[f64] {
        &self.eps[i * BLOCK_LEN + self.lo..i * BLOCK_LEN + self.len]
    }
    /// The counted sample weights β.
    #[inline]
    pub fn beta(&self) -> &[f64] {
        self.beta
    }
    /// The counted values of local column c of output i.
    #[inline]
    pub fn col(&self, i: usize, c: usize) -> &[f64] {
        match self.cols {
            Cols::Owned(v) => {
                let ch = (i * self.m + c) * BLOCK_LEN;
                &v[ch + self.lo..ch + self.len]
            }
            Cols::Block(b, sources) => match sources[c] {
                Source::Theta(j) => &b.dy(i, j)[self.lo..],
                Source::X0(m) => &b.dy0(i, m)[self.lo..],
            },
        }
    }
}

/// Output i's local columns of a chunk, then `extra` when given: in a fixed array for up
/// to [`INLINE_COLUMNS`] columns (no allocation in the pass), else collected into `spill`.
pub(crate) fn columns<'a>(
    ch: &'a Chunk<'_>,
    i: usize,
    extra: Option<&'a [f64]>,
    spill: &'a mut Vec<&'a [f64]>,
) -> Columns<'a> {
    let n = ch.m + usize::from(extra.is_some());
    let all = (0..ch.m).map(|c| ch.col(i, c)).chain(extra);
    if n <= INLINE_COLUMNS {
        let mut a: [&[f64]; INLINE_COLUMNS] = [&[]; INLINE_COLUMNS];
        for (slot, c) in a.iter_mut().zip(all) {
            *slot = c;
        }
        Columns::Inline(a, n)
    } else {
        spill.extend(all);
        Columns::Spilled(spill)
    }
}

/// Most columns a pass holds without allocating.
pub(crate) const INLINE_COLUMNS: usize = 12;

/// The columns of [`columns`].
pub(crate) enum Columns<'a> {
    Inline([&'a [f64]; INLINE_COLUMNS], usize),
    Spilled(&'a [&'a [f64]]),
}

impl<'a> AsRef<[&'a [f64]]> for Columns<'a> {
    fn as_ref(&self) -> &[&'a [f64]] {
        match self {
            Self::Inline(a, n) => &a[..*n],
            Self::Spilled(v) => v,
        }
    }
}

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
    /// local columns of [`local_map`](Self::local_map) when `mode.jacobian`.
    ///
    /// # Errors
    /// Those of the simulation: invalid θ, [`crate::Error::SimulationDiverged`].
    pub(crate) fn pass_blocks<F>(&self, e: usize, p: &DVector<f64>, mode: Pass, mut f: F) -> Result<LocalMap>
    where
        F: FnMut(&Chunk<'_>),
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
            f(&Chunk { k0, lo, len, m, eps: &eps, beta, cols });
            Ok(())
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
        })?;
        Ok(())
    }
}

/// Where a local Jacobian column comes from.
#[derive(Clone, Copy, Debug)]
enum Source {
    /// The sensitivity to model parameter j.
    Theta(usize),
    /// The sensitivity to initial-state component m.
    X0(usize),
}

/// The residual prefilter L(q) run sample by sample over each output's residual and its
/// Jacobian row (one filter state per channel, from rest).
pub(crate) struct ResidualFilter<'f> {
    l: &'f Butterworth,
    eps: Vec<Vec<[f64; 2]>>,
    jac: Vec<Vec<[f64; 2]>>,
    np: usize,
}

impl<'f> ResidualFilter<'f> {
    /// States for `ny` residuals and `ny × np` Jacobian entries.
    pub(crate) fn new(l: &'f Butterworth, ny: usize, np: usize) -> Self {
        let sections = l.sections().len();
        Self { l, eps: vec![vec![[0.0; 2]; sections]; ny], jac: vec![vec![[0.0; 2]; sections]; ny * np], np }
    }

    /// Filters output i's residual and its Jacobian row (length n_free, or empty) in place.
    #[inline]
    pub(crate) fn apply(&mut self, i: usize, eps: &mut f64, row: &mut [f64]) {
        *eps = self.l.step(&mut self.eps[i], *eps);
        for (a, v) in row.iter_mut().enumerate() {
            *v = self.l.step(&mut self.jac[i * self.np + a], *v);
        }
    }

    /// Filters samples `lo..len` of every channel in place: `eps` n_y channels and `cols`
    /// n_y × n_free channels of [`BLOCK_LEN`] each.
    fn apply_block(&mut self, eps: &mut [f64], cols: &mut [f64], lo: usize, len: usize) {
        for (i, z) in self.eps.iter_mut().enumerate() {
            for v in &mut eps[i * BLOCK_LEN + lo..i * BLOCK_LEN + len] {
                *v = self.l.step(z, *v);
            }
        }
        for (c, z) in self.jac.iter_mut().enumerate() {
            for v in &mut cols[c * BLOCK_LEN + lo..c * BLOCK_LEN + len] {
                *v = self.l.step(z, *v);
            }
        }
    }
}

/// One unfiltered sample of a pass: `(k, ε, w, J)`.
pub(crate) type RawSample = (usize, Vec<f64>, Vec<f64>, Vec<f64>);
