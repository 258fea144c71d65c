//! The sums of a pass over one block: weighted Gram matrices and weighted column sums of
//! the local Jacobian columns, as dot products over contiguous arrays, and their map to
//! the optimiser's coordinates.
//!
//! Every dot product runs in independent lanes (four or eight) so that it vectorises; the
//! order of the additions is fixed by the block layout, so a sum is the same for any
//! thread count.

use multiversion::multiversion;
use multiversion::target::target_cfg_f;

/// `Σ_k a_k b_k` over equal-length slices, in eight lanes (FMA where the machine has it:
/// compiled for AVX-512 and AVX2 as well as the baseline, chosen at run time).
#[multiversion(targets("x86_64+avx512f+avx512vl+fma", "x86_64+avx2+fma"))]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    const L: usize = 8;
    let fma = target_cfg_f!(target_feature = "fma");
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; L];
    let (qa, qb) = (a.chunks_exact(L), b.chunks_exact(L));
    let (ra, rb) = (qa.remainder(), qb.remainder());
    for (x, y) in qa.zip(qb) {
        for l in 0..L {
            acc[l] = if fma { x[l].mul_add(y[l], acc[l]) } else { x[l] * y[l] + acc[l] };
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7])) + tail
}

/// `dot(&v[..n − τ], &v[τ..])` for every lag τ in `0..=lags` (n = `v.len()`, lags < n or
/// n = 0): the same numbers as [`dot`] to the bit (the same lanes, added in the same
/// order), in one sweep over `v` a tile at a time rather than one sweep per lag, four
/// lags at once (independent sums, so the additions overlap).
#[multiversion(targets("x86_64+avx512f+avx512vl+fma", "x86_64+avx2+fma"))]
pub(crate) fn lagged_dots(v: &[f64], lags: usize) -> Vec<f64> {
    let fma = target_cfg_f!(target_feature = "fma");
    if fma { lagged::<true>(v, lags) } else { lagged::<false>(v, lags) }
}

/// Lanes of [`lagged_dots`] (those of [`dot`]).
const LANES: usize = 8;

#[inline(always)]
fn lagged<const FMA: bool>(v: &[f64], lags: usize) -> Vec<f64> {
    const L: usize = LANES;
    let n = v.len();
    let lags = lags.min(n.saturating_sub(1));
    let mut acc = vec![[0.0f64; L]; lags + 1];
    // The chunks that every lag has (the longest lag has the fewest), tile by tile.
    let common = (n - lags) / L;
    let mut c0 = 0;
    while c0 < common {
        let c1 = (c0 + TILE).min(common);
        tile_lags::<FMA>(&v[c0 * L..c1 * L], |tau| &v[c0 * L + tau..], &mut acc);
        c0 = c1;
    }
    // The chunks past the common ones, lag by lag, in order.
    for (tau, a) in acc.iter_mut().enumerate() {
        let end = (n - tau) / L;
        sweep::<FMA>(v[common * L..end * L].chunks_exact(L), v[common * L + tau..].chunks_exact(L), a);
    }
    acc.iter()
        .enumerate()
        .map(|(tau, a)| {
            let pairs = n - tau;
            let k = pairs / L * L;
            let tail: f64 = v[k..pairs].iter().zip(&v[k + tau..]).map(|(x, y)| x * y).sum();
            lanes_total(a) + tail
        })
        .collect()
}

/// `Σ_{k=c}^{n−1} v_{k−τ} v_k` for every lag τ in `0..=lags` (n = `v.len()`, `lags ≤ c ≤
/// n`): the lag products whose later value lies past the first c values, which a stream
/// counted before (its carry, see [`LagStream`](super::lags::LagStream)). One sweep a
/// tile at a time, four lags at once, as [`lagged_dots`]. `c < lags` or `c > n` (products
/// that would need values before `v`) is a caller's error: empty in release builds.
#[multiversion(targets("x86_64+avx512f+avx512vl+fma", "x86_64+avx2+fma"))]
pub(crate) fn lagged_dots_after(v: &[f64], c: usize, lags: usize) -> Vec<f64> {
    let fma = target_cfg_f!(target_feature = "fma");
    debug_assert!(lags <= c && c <= v.len(), "lag products past {c} of {} values up to lag {lags}", v.len());
    if c < lags || c > v.len() {
        return Vec::new();
    }
    if fma { lagged_after::<true>(v, c, lags) } else { lagged_after::<false>(v, c, lags) }
}

#[inline(always)]
fn lagged_after<const FMA: bool>(v: &[f64], c: usize, lags: usize) -> Vec<f64> {
    const L: usize = LANES;
    let chunks = (v.len() - c) / L;
    let mut acc = vec![[0.0f64; L]; lags + 1];
    let mut c0 = 0;
    while c0 < chunks {
        let c1 = (c0 + TILE).min(chunks);
        tile_lags::<FMA>(&v[c + c0 * L..c + c1 * L], |tau| &v[c + c0 * L - tau..], &mut acc);
        c0 = c1;
    }
    let k = c + chunks * L;
    acc.iter()
        .enumerate()
        .map(|(tau, a)| {
            let tail: f64 = v[k..].iter().zip(&v[k - tau..]).map(|(x, y)| x * y).sum();
            lanes_total(a) + tail
        })
        .collect()
}

/// Chunks of [`LANES`] per tile of the lag sweeps: 2048 samples, 16 kB, held in the L1
/// cache for every lag.
const TILE: usize = 256;

/// Adds, for every lag τ of `acc`, `x_l y_l` into lane l over the chunks of `x` (whole
/// chunks) paired with those of `y_at(τ)`: four lags at once.
#[inline(always)]
fn tile_lags<'a, const FMA: bool>(x: &'a [f64], y_at: impl Fn(usize) -> &'a [f64], acc: &mut [[f64; LANES]]) {
    const L: usize = LANES;
    let xs = || x.chunks_exact(L);
    let ys = |tau: usize| y_at(tau).chunks_exact(L);
    for (g, accs) in acc.chunks_mut(4).enumerate() {
        let t = 4 * g;
        if let [a0, a1, a2, a3] = accs {
            let mut s = [*a0, *a1, *a2, *a3];
            for ((((x, y0), y1), y2), y3) in xs().zip(ys(t)).zip(ys(t + 1)).zip(ys(t + 2)).zip(ys(t + 3)) {
                for l in 0..L {
                    s[0][l] = madd::<FMA>(x[l], y0[l], s[0][l]);
                    s[1][l] = madd::<FMA>(x[l], y1[l], s[1][l]);
                    s[2][l] = madd::<FMA>(x[l], y2[l], s[2][l]);
                    s[3][l] = madd::<FMA>(x[l], y3[l], s[3][l]);
                }
            }
            [*a0, *a1, *a2, *a3] = s;
        } else {
            for (j, a) in accs.iter_mut().enumerate() {
                sweep::<FMA>(xs(), ys(t + j), a);
            }
        }
    }
}

/// The lanes' total in the order of [`dot`].
#[inline(always)]
fn lanes_total(a: &[f64; LANES]) -> f64 {
    ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]))
}

/// Adds `x_l y_l` into lane l of `a` over the chunks of `xs` (and as many of `ys`).
#[inline(always)]
fn sweep<'a, const FMA: bool>(
    xs: impl Iterator<Item = &'a [f64]>,
    ys: impl Iterator<Item = &'a [f64]>,
    a: &mut [f64; LANES],
) {
    let mut s = *a;
    for (x, y) in xs.zip(ys) {
        for l in 0..LANES {
            s[l] = madd::<FMA>(x[l], y[l], s[l]);
        }
    }
    *a = s;
}

/// `max |v|` (0 for an empty slice; NaN values are skipped), in eight lanes.
pub(crate) fn max_abs(v: &[f64]) -> f64 {
    let mut acc = [0.0f64; 8];
    let q = v.chunks_exact(8);
    let tail = q.remainder().iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for x in q {
        for l in 0..8 {
            // A comparison (false for NaN) rather than `f64::max`: it vectorises.
            let a = x[l].abs();
            acc[l] = if a > acc[l] { a } else { acc[l] };
        }
    }
    acc.iter().fold(tail, |m, a| m.max(*a))
}

/// `Σ_k v_k` in four lanes.
pub(crate) fn sum(v: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let q = v.chunks_exact(4);
    let tail: f64 = q.remainder().iter().sum();
    for x in q {
        for l in 0..4 {
            acc[l] += x[l];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// `Σ_k w_k e_k²` over equal-length slices, in four lanes.
#[inline]
pub(crate) fn weighted_square_sum(e: &[f64], w: &[f64]) -> f64 {
    let n = e.len().min(w.len());
    let (e, w) = (&e[..n], &w[..n]);
    let mut acc = [0.0f64; 4];
    let (qe, qw) = (e.chunks_exact(4), w.chunks_exact(4));
    let (re, rw) = (qe.remainder(), qw.remainder());
    for (x, v) in qe.zip(qw) {
        for l in 0..4 {
            acc[l] += v[l] * x[l] * x[l];
        }
    }
    let tail: f64 = re.iter().zip(rw).map(|(x, v)| v * x * x).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Adds the upper triangle of `Σ_k w_k c_a[k] c_b[k]` over the columns `cols` to `g`
/// (row-major M × M, M = `cols.len()`): k runs over the first n samples, n the length of
/// the shortest column (and of `w`, the weights, or `None` for unit weights).
///
/// Monomorphised for M ≤ 8: one sweep of the block per column a, its sums against the
/// columns b ≥ a (at most eight) held in vector registers on the AVX2 and AVX-512 builds
/// (docs/performance.md, "The Gram matrix a column at a time"); compiled for AVX-512, for
/// AVX2 and FMA as well as the baseline and chosen at run time (crate `multiversion`).
/// Each sum adds lane l over the samples k ≡ l (mod L) in order, the tail past the last
/// whole chunk in lane 0, then the lanes in order, whatever the sweeps' layout.
#[multiversion(targets("x86_64+avx512f+avx512vl+fma", "x86_64+avx2+fma"))]
pub(crate) fn gram(cols: &[&[f64]], w: Option<&[f64]>, g: &mut [f64]) {
    let fma = target_cfg_f!(target_feature = "fma");
    // Eight lanes on AVX-512 for six columns and more (measured with the former single
    // sweep, whose sums needed its 32 registers), four elsewhere: kept so that the numbers
    // stay those of that kernel. The row sweeps were not timed on AVX-512 (no such machine).
    let wide = target_cfg_f!(target_feature = "avx512f");
    macro_rules! fixed {
        ($($m:literal)*) => {
            $(if let Ok(c) = <&[&[f64]; $m]>::try_from(cols) {
                return match (fma, wide && $m >= 6) {
                    (true, true) => gram_fixed::<$m, true, 8>(c, w, g),
                    (true, false) => gram_fixed::<$m, true, 4>(c, w, g),
                    (false, _) => gram_fixed::<$m, false, 4>(c, w, g),
                };
            })*
        };
    }
    fixed!(1 2 3 4 5 6 7 8);
    gram_any(cols, w, g)
}

/// `a b + c`, fused when the target has FMA.
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

#[inline(always)]
fn gram_fixed<const M: usize, const FMA: bool, const L: usize>(
    cols: &[&[f64]; M],
    w: Option<&[f64]>,
    g: &mut [f64],
) {
    let n = cols.iter().map(|c| c.len()).min().unwrap_or(0).min(w.map_or(usize::MAX, <[f64]>::len));
    // Row by row: column a (times the weights) against the columns b ≥ a, their sums held
    // in registers through one sweep of the block (at most eight, so that they stay there).
    macro_rules! rows {
        ($($k:literal)*) => {
            for a in 0..M {
                let row: [f64; 8] = match M - a {
                    $($k => {
                        let others: &[&[f64]; $k] = cols[a..].try_into().expect("M − a columns");
                        gram_row::<$k, FMA, L>(&cols[a][..n], others, w.map(|w| &w[..n]))
                    })*
                    _ => unreachable!("at most eight columns"),
                };
                for (b, s) in (a..M).zip(row) {
                    g[a * M + b] += s;
                }
            }
        };
    }
    rows!(1 2 3 4 5 6 7 8);
}

/// `Σ_k w_k c_a[k] c_b[k]` over k < n = `ca.len()` (c_a = `ca`) for each of the K columns
/// `others` (each, and `w` when given, at least n long), each in L lanes (lane l sums the
/// samples k ≡ l mod L in order, the tail past the last whole chunk in lane 0) added in
/// lane order: the first K entries of the result.
#[inline(always)]
fn gram_row<const K: usize, const FMA: bool, const L: usize>(
    ca: &[f64],
    others: &[&[f64]; K],
    w: Option<&[f64]>,
) -> [f64; 8] {
    let n = ca.len();
    let mut acc = [[0.0f64; L]; K];
    let quads = n / L;
    for q in 0..quads {
        let base = q * L;
        let mut wa = [0.0f64; L];
        wa.copy_from_slice(&ca[base..base + L]);
        if let Some(w) = w {
            for l in 0..L {
                wa[l] *= w[base + l];
            }
        }
        for (s, cb) in acc.iter_mut().zip(others) {
            let cb = &cb[base..base + L];
            for l in 0..L {
                s[l] = madd::<FMA>(wa[l], cb[l], s[l]);
            }
        }
    }
    for k in quads * L..n {
        let wa = w.map_or(1.0, |w| w[k]) * ca[k];
        for (s, cb) in acc.iter_mut().zip(others) {
            s[0] = madd::<FMA>(wa, cb[k], s[0]);
        }
    }
    let mut row = [0.0f64; 8];
    for (r, s) in row.iter_mut().zip(&acc) {
        *r = s.iter().sum::<f64>();
    }
    row
}

/// [`gram`] for any number of columns: one dot product per pair.
fn gram_any(cols: &[&[f64]], w: Option<&[f64]>, g: &mut [f64]) {
    let m = cols.len();
    let mut tmp = Vec::new();
    for a in 0..m {
        tmp.clear();
        match w {
            Some(w) => tmp.extend(w.iter().zip(cols[a]).map(|(w, c)| w * c)),
            None => tmp.extend_from_slice(cols[a]),
        }
        for b in a..m {
            g[a * m + b] += dot(&tmp, cols[b]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{gram_fixed, madd};

    /// `Σ_k w_k c_a[k] c_b[k]` as the lanes are defined: lane l sums the samples k ≡ l mod
    /// L of the whole chunks in order (fused where `FMA`), the tail goes to lane 0, and the
    /// lanes are added in order.
    /// n: the shortest of the columns and the weights.
    fn lanes<const FMA: bool, const L: usize>(ca: &[f64], cb: &[f64], w: Option<&[f64]>, n: usize) -> f64 {
        let mut acc = [0.0f64; L];
        for (k, (x, y)) in ca[..n].iter().zip(cb).enumerate() {
            let l = if k < n / L * L { k % L } else { 0 };
            acc[l] = madd::<FMA>(w.map_or(1.0, |w| w[k]) * x, *y, acc[l]);
        }
        acc.iter().sum()
    }

    fn check<const M: usize, const FMA: bool, const L: usize>(cols: &[Vec<f64>], w: Option<&[f64]>) {
        let c: [&[f64]; M] = std::array::from_fn(|a| cols[a].as_slice());
        let n = c.iter().map(|c| c.len()).chain(w.map(<[f64]>::len)).min().unwrap_or(0);
        let mut g = vec![0.5; M * M];
        gram_fixed::<M, FMA, L>(&c, w, &mut g);
        for a in 0..M {
            for b in 0..M {
                let want = if b >= a { 0.5 + lanes::<FMA, L>(c[a], c[b], w, n) } else { 0.5 };
                assert_eq!(
                    g[a * M + b].to_bits(),
                    want.to_bits(),
                    "M {M}, L {L}, fma {FMA}: entry ({a}, {b})"
                );
            }
        }
    }

    /// Each sum of the Gram is its lanes' sum to the bit, whatever the number of columns,
    /// lanes, weights and tail, over the shortest of the columns and weights: the
    /// additions' order is fixed (module doc). A 259-sample block has a tail of 3.
    #[test]
    fn the_gram_is_the_sum_of_its_lanes_to_the_bit() {
        // (samples of column 0, extra samples of column a: a × this, weights)
        let cases = [(0, 0, 0), (3, 0, 3), (256, 0, 256), (259, 0, 259), (259, 1, 264), (259, 2, 250)];
        for (n, longer, n_w) in cases {
            let cols: Vec<Vec<f64>> = (0..8)
                .map(|a| {
                    let len = n + a * longer;
                    (0..len).map(|k| ((7 * a + 3 * k) as f64 * 0.37).sin() * 1e3f64.powi(a % 3)).collect()
                })
                .collect();
            let w: Vec<f64> = (0..n_w).map(|k| 1.0 + (k as f64 * 0.11).cos().abs()).collect();
            for w in [None, Some(w.as_slice())] {
                macro_rules! each {
                    ($($m:literal)*) => {$(
                        check::<$m, true, 4>(&cols, w);
                        check::<$m, false, 4>(&cols, w);
                        check::<$m, true, 8>(&cols, w);
                    )*};
                }
                each!(1 2 3 4 5 6 7 8);
            }
        }
    }
}
