//! One named signal of a log and its values: [`Channel`], [`Values`], and the finiteness
//! test the readers and validators share ([`all_finite`]).

/// A channel's values, shared: cloning an [`Experiment`](super::Experiment), or preparing a fit on it,
/// shares the samples instead of copying them (a fit's memory beyond the data stays
/// O(n_θ²) where its model reads the channels as they are). Build one from a `Vec<f64>`
/// with `.into()`; [`std::sync::Arc::make_mut`] edits it (copying only if it is shared).
pub type Values = std::sync::Arc<Vec<f64>>;

/// One named signal: values at `t_k` (or period means over `[t_k, t_k + h)`, as the
/// channel's documentation says), length N.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Channel name, e.g. `ud`, `w_m`, `temperature`.
    pub name: String,
    /// SI unit, e.g. `V`, `rad/s`, `K`; empty for dimensionless.
    pub unit: String,
    /// One value per sample, length N (shared, see [`Values`]).
    pub values: Values,
}

impl Channel {
    /// A channel called `name` in `unit` with the given values (not yet validated: that
    /// happens when an [`Experiment`](super::Experiment) is built from it).
    pub fn new(name: impl Into<String>, unit: impl Into<String>, values: Vec<f64>) -> Self {
        Self { name: name.into(), unit: unit.into(), values: values.into() }
    }
}

/// Whether every value of `c` is finite: `v · 0` is NaN exactly for a non-finite v, summed
/// in four independent lanes so that the loop vectorises (no branch per value; a caller
/// then seeks the first bad value only where there is one).
#[inline]
pub(crate) fn all_finite(c: &[f64]) -> bool {
    let mut acc = [0.0f64; 4];
    let mut chunks = c.chunks_exact(4);
    for q in &mut chunks {
        for l in 0..4 {
            acc[l] += q[l] * 0.0;
        }
    }
    let tail: f64 = chunks.remainder().iter().map(|v| v * 0.0).sum();
    !(acc[0] + acc[1] + acc[2] + acc[3] + tail).is_nan()
}
