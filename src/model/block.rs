//! Blocks of samples in structure-of-arrays form: what a simulation with sensitivities
//! hands the estimator, [`BLOCK_LEN`] samples at a time, and the optional whole-block
//! kernel a model may offer ([`BlockKernel`]) so that the per-sample work runs without a
//! call per sample.
//!
//! Source: the forward sensitivity recursion (Ljung, *System Identification*, 2nd ed.,
//! 10.3) run over a block instead of a sample; the layout is the one SIMD loops want
//! (one contiguous array per channel).

use crate::data::{Values, all_finite};

/// Samples in one block (the last block of a record may be shorter).
pub const BLOCK_LEN: usize = 256;

/// One block of a simulation: outputs and, on request, their sensitivities, each channel
/// a contiguous array of [`BLOCK_LEN`] values of which the first [`len`](Self::len) are set.
///
/// Channels: `y` n_y (`ŷ_i`), `dy` n_y × n_θ (`∂ŷ_i/∂θ_j` at channel `i n_θ + j`), `dy0`
/// n_y × n_x0 (`∂ŷ_i/∂x₀_m` at channel `i n_x0 + m`, n_x0 = n_x when the initial-state
/// sensitivity is asked for, else 0).
#[derive(Clone, Debug)]
pub struct Block {
    /// Index of the block's first sample in the record.
    pub k0: usize,
    /// Samples set in this block (≤ [`BLOCK_LEN`]).
    pub len: usize,
    /// Whether `dy` and `dy0` are computed.
    pub sensitivities: bool,
    n_y: usize,
    n_theta: usize,
    n_x0: usize,
    y: Vec<f64>,
    dy: Vec<f64>,
    dy0: Vec<f64>,
}

impl Block {
    /// An empty block for `n_y` outputs, `n_theta` parameters and `n_x0` initial-state
    /// directions (sensitivity channels allocated only when `sensitivities`).
    pub fn new(n_y: usize, n_theta: usize, n_x0: usize, sensitivities: bool) -> Self {
        let (nt, n0) = if sensitivities { (n_theta, n_x0) } else { (0, 0) };
        Self {
            k0: 0,
            len: 0,
            sensitivities,
            n_y,
            n_theta: nt,
            n_x0: n0,
            y: vec![0.0; n_y * BLOCK_LEN],
            dy: vec![0.0; n_y * nt * BLOCK_LEN],
            dy0: vec![0.0; n_y * n0 * BLOCK_LEN],
        }
    }
    /// Number of outputs n_y.
    pub fn n_outputs(&self) -> usize {
        self.n_y
    }
    /// Number of parameters with a sensitivity channel (n_θ, or 0 without sensitivities).
    pub fn n_theta(&self) -> usize {
        self.n_theta
    }
    /// Number of initial-state directions n_x0 (0 when not asked for).
    pub fn n_x0(&self) -> usize {
        self.n_x0
    }
    /// `ŷ_i` over the block, length [`len`](Self::len).
    pub fn y(&self, i: usize) -> &[f64] {
        &self.y[i * BLOCK_LEN..i * BLOCK_LEN + self.len]
    }
    /// `∂ŷ_i/∂θ_j` over the block, length [`len`](Self::len).
    pub fn dy(&self, i: usize, j: usize) -> &[f64] {
        let c = i * self.n_theta + j;
        &self.dy[c * BLOCK_LEN..c * BLOCK_LEN + self.len]
    }
    /// `∂ŷ_i/∂x₀_m` over the block, length [`len`](Self::len).
    pub fn dy0(&self, i: usize, m: usize) -> &[f64] {
        let c = i * self.n_x0 + m;
        &self.dy0[c * BLOCK_LEN..c * BLOCK_LEN + self.len]
    }
    /// All channels for writing: `(y, dy, dy0)`, each channel [`BLOCK_LEN`] long, channel
    /// order as in the type's documentation.
    pub fn channels_mut(&mut self) -> (&mut [f64], &mut [f64], &mut [f64]) {
        (&mut self.y, &mut self.dy, &mut self.dy0)
    }
    /// Whether every set value is finite; otherwise the offset of the first sample in the
    /// block with a non-finite value.
    pub fn first_non_finite(&self) -> Option<usize> {
        let channels =
            self.y.chunks(BLOCK_LEN).chain(self.dy.chunks(BLOCK_LEN)).chain(self.dy0.chunks(BLOCK_LEN));
        let mut first: Option<usize> = None;
        for c in channels {
            let c = &c[..self.len];
            if !all_finite(c) {
                let k = c.iter().position(|v| !v.is_finite());
                first = match (first, k) {
                    (Some(a), Some(b)) => Some(a.min(b)),
                    (a, b) => a.or(b),
                };
            }
        }
        first
    }
}

impl SimState {
    /// Whether the state and its sensitivities are all finite.
    pub fn is_finite(&self) -> bool {
        all_finite(&self.x) && all_finite(&self.s) && all_finite(&self.s0)
    }
}

/// The state a blocked simulation carries from block to block.
#[derive(Clone, Debug)]
pub struct SimState {
    /// Next sample to produce.
    pub k: usize,
    /// State `x_k`, length n_x.
    pub x: Vec<f64>,
    /// `∂x_k/∂θ`, row-major n_x × n_θ.
    pub s: Vec<f64>,
    /// `∂x_k/∂x₀`, row-major n_x × n_x (`s0[i n_x + m] = ∂x_i/∂x₀_m`).
    pub s0: Vec<f64>,
    /// Whether `∂x/∂x₀` is still non-zero (false once a restart or decay has cleared it).
    pub live0: bool,
    /// Working space a [`BlockKernel`] may keep from block to block (empty at the start).
    pub scratch: Vec<f64>,
}

impl SimState {
    /// The state at sample 0: `x₀`, zero parameter sensitivity, identity `∂x/∂x₀` (live
    /// when `x0_sensitivity`).
    pub fn new(x0: &[f64], n_theta: usize, x0_sensitivity: bool) -> Self {
        let nx = x0.len();
        let mut s0 = vec![0.0; nx * nx];
        for i in 0..nx {
            s0[i * nx + i] = 1.0;
        }
        Self {
            k: 0,
            x: x0.to_vec(),
            s: vec![0.0; nx * n_theta],
            s0,
            live0: x0_sensitivity,
            scratch: Vec::new(),
        }
    }

    /// `len` values of [`scratch`](Self::scratch) for arrays of [`BLOCK_LEN`] (channel c at
    /// `c · BLOCK_LEN`), placed away from the arrays a kernel reads or writes beside them
    /// (`hot`: the addresses of the block's channels and of the data the block reads, as
    /// numbers) modulo [`BLOCK_LEN`] values
    /// (2 kB, so every channel of each lies at the same address bits): a load within a few
    /// cache lines of an earlier store modulo 4 kB waits for that store (4K aliasing;
    /// Intel® 64 and IA-32 Architectures Optimization Reference Manual, "4-KByte memory
    /// access aliasing"; AMD's Software Optimization Guide for Zen 4, 2.12), which doubled
    /// a pass where the allocator aligned every buffer to a page. The offset is a whole
    /// number of cache lines, the farthest from every hot address of 32 candidates. The
    /// values are left as they were (a kernel writes them before it reads them).
    pub(crate) fn scratch_apart(&mut self, len: usize, hot: &[usize]) -> &mut [f64] {
        const LINE: usize = 8;
        const PERIOD: usize = BLOCK_LEN * std::mem::size_of::<f64>();
        // A kernel asks for a few blocks' worth: `len + BLOCK_LEN` cannot overflow then, and
        // saturating keeps the slice below in range were it to.
        let len = len.min(usize::MAX - BLOCK_LEN);
        self.scratch.resize(len + BLOCK_LEN, 0.0);
        let base = self.scratch.as_ptr() as usize;
        let apart = |shift: &usize| {
            let r = (base + shift * std::mem::size_of::<f64>()) % PERIOD;
            hot.iter()
                .map(|&h| {
                    let d = (r + PERIOD - h % PERIOD) % PERIOD;
                    d.min(PERIOD - d)
                })
                .min()
                .unwrap_or(PERIOD)
        };
        let shift = (0..BLOCK_LEN / LINE).map(|j| j * LINE).max_by_key(apart).unwrap_or(0);
        &mut self.scratch[shift..shift + len]
    }
}

/// What a block run needs beyond the model's data: the record length, the restart period
/// and the measured outputs a restart takes the state from.
#[derive(Clone, Copy, Debug)]
pub struct BlockContext<'a> {
    /// Record length N.
    pub n: usize,
    /// Restart period (k-step-ahead prediction), `None` = simulation.
    pub horizon: Option<usize>,
    /// Measured outputs, n_y columns of length N ([`Prepared::y`](super::Prepared::y)).
    pub measured: &'a [Values],
}

impl BlockContext<'_> {
    /// Whether the state restarts from the measurement after the output at sample k.
    #[inline(always)]
    pub fn restarts_at(&self, k: usize) -> bool {
        matches!(self.horizon, Some(h) if k.is_multiple_of(h))
    }
}

/// A whole-block simulation kernel of a model with inputs `I` and coefficients `C`: the
/// same numbers as the model's per-sample [`step`](super::GreyBoxModel::step) and
/// [`Sensitivities`](super::Sensitivities), computed a block at a time.
pub trait BlockKernel<I, C>: Sync {
    /// Fills `block` for samples `state.k .. state.k + block.len` (`block.k0 = state.k`
    /// and `block.len` are set by the caller): at each sample k the output `ŷ_k` and, when
    /// `block.sensitivities`, `∂ŷ_k/∂θ` and (for `block.n_x0() > 0`) `∂ŷ_k/∂x₀` (zero once
    /// `state.live0` is false); then, when `ctx.restarts_at(k)`, the state restarts from
    /// the measured `y_k` with zero sensitivities and `live0` false; then, for
    /// `k + 1 < ctx.n`, the state (and its sensitivities when asked for) advances to k + 1.
    /// Leaves `state.k = block.k0 + block.len`. Non-finite values are left for the caller
    /// to find.
    fn run(&self, c: &C, inputs: &I, ctx: &BlockContext<'_>, state: &mut SimState, block: &mut Block);

    /// Whether a non-finite output or sensitivity at any sample of a block leaves the state
    /// or one of its sensitivities non-finite at the block's end when the block has no
    /// restart (true of a recursion whose outputs are its states and whose step is a sum
    /// of products: NaN and ∞ survive both). Then a block without restarts is searched for
    /// the first non-finite sample only when its end state is non-finite. The default,
    /// `false`, searches every block.
    fn non_finite_persists(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scratch is placed whole cache lines into its buffer, within a line of the
    /// largest distance possible (modulo the 2 kB channel period) from its h hot addresses,
    /// which is at least `period / 2h`: for hot addresses all on one page boundary (as an
    /// allocator that aligns every buffer to a page gives them), half the period away.
    #[test]
    fn scratch_lies_apart_from_the_hot_arrays() {
        let period = BLOCK_LEN * 8;
        let distance = |a: usize, b: usize| {
            let d = (a + period - b % period) % period;
            d.min(period - d)
        };
        let page = vec![0.0f64; 3 * BLOCK_LEN];
        let aligned = page.as_ptr().wrapping_add(BLOCK_LEN - page.as_ptr() as usize / 8 % BLOCK_LEN);
        let spread = [aligned, aligned.wrapping_add(40), aligned.wrapping_add(130)].map(|p| p as usize);
        for hot in [vec![aligned as usize; 1], spread.to_vec()] {
            let mut st = SimState::new(&[0.0, 0.0], 3, false);
            let len = 5 * BLOCK_LEN;
            let s = st.scratch_apart(len, &hot);
            assert_eq!(s.len(), len);
            let at = s.as_ptr() as usize;
            let offset = (at - st.scratch.as_ptr() as usize) / 8;
            assert_eq!(offset % 8, 0, "whole cache lines");
            let least = period / (2 * hot.len()) - 32;
            for &h in &hot {
                assert!(distance(at, h) >= least, "{} bytes from a hot array", distance(at, h));
            }
        }
    }
}
