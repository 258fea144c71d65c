//! The lag products of a residual sequence, summed as it streams past: what its
//! normalised autocorrelation (the whiteness test of MODEL.md §5; Ljung 1999, 16.6) needs,
//! without keeping the sequence (O(max_lag) memory instead of O(N)).

use super::gram::{lagged_dots, lagged_dots_after, sum};

/// Lags of the residual whiteness test of a fit: the autocorrelation at lags 1..=25, as
/// MATLAB's `resid` by default (Ljung 1999, 16.6).
pub const WHITENESS_LAGS: usize = 25;

/// Values a fit's statistics gather of a residual sequence before they sum their lag
/// products (with those of the last max_lag values before them): for a sequence of at most this many values the sums are those of one sweep
/// over the whole sequence to the bit; for a longer one they agree to rounding, and they
/// never depend on how the sequence was cut into pushes.
pub const LAG_CHUNK: usize = 16_384;

/// The lag sums of one sequence `e_0 … e_{n−1}` (one output's residuals over one
/// experiment), as a fit's statistics stream them ([`Sums::lag_sums`](super::Sums)): enough
/// for the autocorrelation about any mean (`Σ (e_k − m)(e_{k+τ} − m) = dots[τ] − m
/// (Σ_{k<n−τ} e_k + Σ_{k≥τ} e_k) + (n − τ) m²`, each partial sum the total less τ values at
/// an end), which [`whiteness_of`](crate::estimate::metrics::whiteness_of) takes. O(max_lag)
/// memory. Built only by the crate, so its parts always agree.
#[derive(Clone, Debug, PartialEq)]
pub struct LagSums {
    n: usize,
    total: f64,
    dots: Vec<f64>,
    head: Vec<f64>,
    tail: Vec<f64>,
}

impl LagSums {
    /// Number of values n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// `Σ_k e_k` \[unit of e\].
    pub fn total(&self) -> f64 {
        self.total
    }

    /// `dots[τ] = Σ_{k=0}^{n−1−τ} e_k e_{k+τ}` for τ = 0..=max_lag, length max_lag + 1 (0 for
    /// τ ≥ n) \[unit of e squared\].
    pub fn dots(&self) -> &[f64] {
        &self.dots
    }

    /// The first min(n, max_lag) values \[unit of e\].
    pub fn head(&self) -> &[f64] {
        &self.head
    }

    /// The last min(n, max_lag) values, in order \[unit of e\].
    pub fn tail(&self) -> &[f64] {
        &self.tail
    }

    /// The lag sums of a whole sequence `e` up to lag `max_lag` (those of a
    /// [`LagStream`] that took `e`); `max_lag + 1` sums are kept, so callers clip it to the
    /// sequence first.
    pub(crate) fn of(e: &[f64], max_lag: usize) -> Self {
        let mut s = LagStream::new(max_lag);
        s.push(e);
        s.finish()
    }

    /// The largest lag these sums hold.
    pub fn max_lag(&self) -> usize {
        self.dots.len().saturating_sub(1)
    }

    /// `Σ_k (e_k − m)(e_{k+τ} − m)` over the n − τ pairs at lag `tau ≤ min(max_lag, n)`
    /// about the mean `m` (callers keep to that range: the crate's [`whiteness_of`](crate::estimate::metrics::whiteness_of) does).
    pub(crate) fn centred(&self, tau: usize, m: f64) -> f64 {
        let pairs = self.n - tau;
        // Σ over the first and the last n − τ values: the total less τ values at an end.
        let first = self.total - sum(&self.tail[self.tail.len() - tau..]);
        let last = self.total - sum(&self.head[..tau]);
        self.dots[tau] - m * (first + last) + pairs as f64 * m * m
    }
}

/// A sequence's [`LagSums`] accumulated from pieces in order (a pass's blocks), keeping
/// only the last `max_lag` values (the carry, whose products with later values are still
/// to come) and at most [`LAG_CHUNK`] pending ones: the chunks start at fixed positions
/// of the sequence, so the sums do not depend on the pieces' sizes.
#[derive(Clone, Debug)]
pub(crate) struct LagStream {
    max_lag: usize,
    chunk: usize,
    n: usize,
    total: f64,
    dots: Vec<f64>,
    head: Vec<f64>,
    /// The carry (`carry` values already counted) followed by the pending values.
    buf: Vec<f64>,
    carry: usize,
}

impl LagStream {
    /// An empty stream summing the lag products up to lag `max_lag` (`max_lag + 1` sums).
    pub(crate) fn new(max_lag: usize) -> Self {
        // A first chunk of at least max_lag values leaves a full carry for every later one.
        let chunk = LAG_CHUNK.max(max_lag);
        Self {
            max_lag,
            chunk,
            n: 0,
            total: 0.0,
            dots: vec![0.0; max_lag + 1],
            head: Vec::new(),
            // Grown as values come (a short sequence keeps a short buffer), to at most
            // max_lag + chunk values.
            buf: Vec::new(),
            carry: 0,
        }
    }

    /// Appends the values `e` to the sequence.
    pub(crate) fn push(&mut self, mut e: &[f64]) {
        while !e.is_empty() {
            let room = self.chunk - (self.buf.len() - self.carry);
            let (now, later) = e.split_at(room.min(e.len()));
            let need = self.buf.len() + now.len();
            if need > self.buf.capacity() {
                let cap = (2 * self.buf.capacity()).max(need).min(self.max_lag + self.chunk);
                self.buf.reserve_exact(cap - self.buf.len());
            }
            self.buf.extend_from_slice(now);
            e = later;
            if self.buf.len() - self.carry == self.chunk {
                self.flush();
            }
        }
    }

    /// Sums the pending values' lag products (with the carry's) and keeps the last
    /// max_lag values as the carry.
    fn flush(&mut self) {
        let fresh = &self.buf[self.carry..];
        if fresh.is_empty() {
            return;
        }
        let dots = if self.n == 0 {
            lagged_dots(fresh, self.max_lag)
        } else {
            // Every chunk after the first has a full carry (`chunk ≥ max_lag`).
            lagged_dots_after(&self.buf, self.carry, self.max_lag)
        };
        for (d, x) in self.dots.iter_mut().zip(dots) {
            *d += x;
        }
        self.total += sum(fresh);
        let more = (self.max_lag - self.head.len()).min(fresh.len());
        self.head.extend_from_slice(&fresh[..more]);
        self.n += fresh.len();
        let keep = self.max_lag.min(self.buf.len());
        self.buf.drain(..self.buf.len() - keep);
        self.carry = keep;
    }

    /// The lag sums of the sequence pushed.
    pub(crate) fn finish(mut self) -> LagSums {
        self.flush();
        // The carry is at most max_lag values: no chunk-sized buffer outlives the stream.
        self.buf.shrink_to_fit();
        LagSums { n: self.n, total: self.total, dots: self.dots, head: self.head, tail: self.buf }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic values of mixed sign and scale.
    fn sequence(n: usize) -> Vec<f64> {
        (0..n).map(|k| ((k as f64 * 0.7).sin() + 0.3) * (1.0 + (k % 7) as f64)).collect()
    }

    /// Up to one chunk the sums are one sweep's to the bit; beyond, every lag's dot agrees
    /// with a direct sum to rounding, and any cut into pushes gives the same bits.
    #[test]
    fn streamed_sums_are_the_direct_ones() {
        for &(n, lags) in &[(0, 3), (1, 3), (5, 25), (100, 25), (LAG_CHUNK, 25), (3 * LAG_CHUNK + 77, 25)] {
            let e = sequence(n);
            let whole = LagSums::of(&e, lags);
            assert_eq!(whole.n, n);
            assert_eq!(whole.head, e[..lags.min(n)].to_vec());
            assert_eq!(whole.tail, e[n - lags.min(n)..].to_vec());
            if n <= LAG_CHUNK {
                let mut direct = lagged_dots(&e, lags);
                direct.resize(lags + 1, 0.0);
                assert_eq!(whole.dots, direct, "n = {n}");
                assert_eq!(whole.total.to_bits(), sum(&e).to_bits());
            }
            for tau in 0..=lags {
                let exact: f64 = (0..n.saturating_sub(tau)).map(|k| e[k] * e[k + tau]).sum();
                let scale: f64 = (0..n.saturating_sub(tau)).map(|k| (e[k] * e[k + tau]).abs()).sum();
                assert!((whole.dots[tau] - exact).abs() <= 1e-13 * scale.max(1.0), "n = {n}, τ = {tau}");
            }
            for piece in [1, 7, 256, 5000] {
                let mut s = LagStream::new(lags);
                e.chunks(piece).for_each(|c| s.push(c));
                assert_eq!(s.finish(), whole, "n = {n}, pieces of {piece}");
            }
        }
    }

    /// The finished sums hold their few values, not the stream's buffer (a fit of many
    /// experiments keeps one per experiment and output until its statistics are done).
    #[test]
    fn finished_sums_keep_no_buffer() {
        for n in [10, 3 * LAG_CHUNK + 5] {
            let s = LagSums::of(&sequence(n), 25);
            assert!(s.tail.capacity() <= 2 * 25, "n = {n}: capacity {}", s.tail.capacity());
        }
    }

    /// A lag beyond the chunk length still pairs values across chunks.
    #[test]
    fn lags_longer_than_a_chunk() {
        let (n, lags) = (2 * LAG_CHUNK + 3000, LAG_CHUNK + 10);
        let e = sequence(n);
        let s = LagSums::of(&e, lags);
        for tau in [0, 1, LAG_CHUNK - 1, LAG_CHUNK, lags] {
            let exact: f64 = (0..n - tau).map(|k| e[k] * e[k + tau]).sum();
            let scale: f64 = (0..n - tau).map(|k| (e[k] * e[k + tau]).abs()).sum();
            assert!((s.dots[tau] - exact).abs() <= 1e-13 * scale, "τ = {tau}");
        }
    }

    /// The centred sums are the direct ones about any mean.
    #[test]
    fn centred_sums() {
        let e = sequence(300);
        let s = LagSums::of(&e, 10);
        for tau in [0, 1, 9, 10] {
            let m = 0.37;
            let direct: f64 = (0..300 - tau).map(|k| (e[k] - m) * (e[k + tau] - m)).sum();
            assert!((s.centred(tau, m) - direct).abs() < 1e-10, "τ = {tau}");
        }
    }
}
