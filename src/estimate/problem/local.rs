//! What a pass hands on and how it maps to the optimiser: the pass's mode ([`Pass`]), a
//! block of residuals and local Jacobian columns ([`Chunk`]), the experiment's local
//! columns ([`LocalMap`]) and the residual prefilter ([`ResidualFilter`]); no pass here.

use crate::estimate::arrowhead::Arrowhead;
use crate::estimate::filter::Butterworth;
use crate::model::{BLOCK_LEN, Block};
use nalgebra::DMatrix;

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
    pub(super) eps: &'a [f64],
    pub(super) beta: &'a [f64],
    pub(super) cols: Cols<'a>,
}

/// Where a chunk's Jacobian columns are: copied (and prefiltered), or in the block.
pub(super) enum Cols<'a> {
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

/// Where a local Jacobian column comes from.
#[derive(Clone, Copy, Debug)]
pub(super) enum Source {
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
    pub(super) fn apply_block(&mut self, eps: &mut [f64], cols: &mut [f64], lo: usize, len: usize) {
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

/// Adds a local Gram's upper triangle (row-major m × m), chained, into `out` (n_free ×
/// n_free, upper triangle): `out[g_a, g_b] += dθ_a dθ_b local[a, b]`.
pub(crate) fn scatter_gram(map: &LocalMap, local: &[f64], out: &mut DMatrix<f64>) {
    let m = map.len();
    for a in 0..m {
        for b in a..m {
            let (ga, gb) = (map.global[a], map.global[b]);
            let (r, c) = (ga.min(gb), ga.max(gb));
            out[(r, c)] += map.dtheta[a] * map.dtheta[b] * local[a * m + b];
        }
    }
}

/// [`scatter_gram`] into an arrowhead matrix (both triangles of its blocks): the local
/// columns of one experiment are shared ones and its own.
pub(crate) fn scatter_arrow(map: &LocalMap, local: &[f64], out: &mut Arrowhead) {
    let m = map.len();
    for a in 0..m {
        for b in a..m {
            let v = map.dtheta[a] * map.dtheta[b] * local[a * m + b];
            out.add_symmetric(map.global[a], map.global[b], v);
        }
    }
}
