//! The regression Gram of the setup checks ([`crate::pmsm::checks::detect`]), streamed: the five signals
//! the voltage equations need (`u_d, u_q, i_d, i_q, w_m`) are low-passed together, lane by
//! lane, a chunk at a time, and the Gram of the base columns is summed over the intervals
//! without forming a row matrix, the structural zeros of the d and q rows skipped. For the
//! terminal voltage nothing the size of the record is allocated (a reference input's
//! applied voltage is formed first).
//!
//! The zero-phase filter is [`Butterworth::filtfilt`] (odd reflection, steady-state start,
//! forward then backward; Gustafsson 1996) with the same operations in the same order on
//! every lane, so each lane equals `filtfilt` of its signal bit for bit; the Gram sums the
//! products of every interval, chunk by chunk from the record's end (the order in which
//! the backward pass finishes them), so it equals a dense `ΦᵀΦ` to rounding.

use crate::error::Result;
use crate::estimate::filter::{Biquad, Butterworth};
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::{SQRT_2_3, VoltageInput, driving_voltage};
use multiversion::multiversion;
use nalgebra::DMatrix;

/// Order and cutoff (relative to the sample rate) of the scan's zero-phase prefilter.
const SCAN_FILTER_ORDER: usize = 4;
const SCAN_CUTOFF: f64 = 0.05;

/// Base columns of the scan (see [`crate::pmsm::checks::detect`]), then the voltage at
/// index `BASE`, then the [`OFFSETS`] columns of a constant offset of the currents.
pub(crate) const BASE: usize = 6;

/// The offset columns after the voltage: `1` (d rows), `1` (q rows), `ω_m` (d rows) on the
/// intervals where the rotor turns faster than [`TURNING`] of the log's top speed (0
/// elsewhere), then `1` (d rows), `1` (q rows) on the others. A constant offset `c` of the
/// logged currents adds `−R_s c_d` and `n_p L_q ω_m c_q` to the d rows and `−R_s c_q` to
/// the q rows (its `−n_p L_d ω_m c_d` there is the back-EMF's column, absorbed by `k_e`;
/// MODEL.md §2): the regression of `pmsm::fit::current_offset`. A phase current's offset
/// is constant in the stator frame: in dq it turns with the rotor and averages out where the
/// rotor turns, but looks constant at standstill. So the offset is read from the turning
/// rows, and the standstill rows' own constants absorb what either offset leaves there.
pub(crate) const OFFSETS: usize = 5;

/// Share of a log's top speed above which an interval counts in the offset columns.
pub(crate) const TURNING: f64 = 0.1;

/// The cross columns after the offsets, summed in the Gram of the logs as given only
/// ([`scan_grams`]' [`IDENTITY`]): `di_q/dt`, `ω_m i_d` (d rows), `di_d/dt`, `ω_m i_q` (q
/// rows). A dq frame turned by a small δ from an interior-magnet rotor's adds `δ (L_q − L_d)`
/// times `di_q/dt − n_p ω_m i_d` to the d rows and `di_d/dt + n_p ω_m i_q` to the q rows
/// (beside the back-EMF's `√(2/3) k_e ω_m sin δ` in the d rows): the regression of
/// `pmsm::fit::angle_offset`.
pub(crate) const CROSS: usize = 4;

/// Side of the scan's Gram: the base columns, the voltage, the offset and the cross columns.
pub(crate) const GRAM: usize = BASE + 1 + OFFSETS + CROSS;

/// Filtered signals per sample: `[u_d, u_q, i_d, i_q, w_m]`.
const LANES: usize = 5;

/// Columns of a d row that can be non-zero: `i_d`, `di_d/dt`, `−ω_m i_q`, `u_d`, the
/// offset columns `1`, `ω_m` (turning) and `1` (standstill), then the cross columns
/// `di_q/dt`, `ω_m i_d`.
const D_COLUMNS: [usize; 9] = [0, 1, 3, 6, 7, 9, 10, 12, 13];
/// Columns of a q row that can be non-zero: `i_q`, `ω_m i_d`, `di_q/dt`, `√(2/3) ω_m`,
/// `u_q`, the offset columns `1` (turning) and `1` (standstill), then the cross columns
/// `di_d/dt`, `ω_m i_q`.
const Q_COLUMNS: [usize; 9] = [0, 2, 4, 5, 6, 8, 11, 14, 15];
/// The entries of each row before its cross columns.
const PLAIN: usize = 7;

/// Samples per chunk of the streamed zero-phase filter ([`filtfilt_chunks`]).
const CHUNK: usize = 4096;

/// The delays of the filter's cascade: per section the quad's two delays (lanes 0–3) and
/// the fifth lane's.
#[derive(Clone, Debug)]
struct Delays(Vec<([[f64; 4]; 2], [f64; 2])>);

impl Delays {
    /// Every section at its steady state `zi` (per unit input, `sosfilt_zi`) under the
    /// constant input `start`.
    fn steady(zi: &[[f64; 2]], start: [f64; LANES]) -> Self {
        let quad = [start[0], start[1], start[2], start[3]];
        Self(
            zi.iter()
                .map(|s| {
                    ([quad.map(|v| s[0] * v), quad.map(|v| s[1] * v)], [s[0] * start[4], s[1] * start[4]])
                })
                .collect(),
        )
    }
}

/// Zero-phase low-pass of the scan's five signals at once (over the shortest one's
/// length), streamed: `f(k0, chunk, next)` receives samples `k0 .. k0 + chunk.len()` of the
/// result (lane `l` of sample k is `bw.filtfilt(x[l])[k]`, bit for bit) and the sample after
/// them (`None` for the last), chunk by chunk from the end of the record to its start.
/// Empty signals give no call.
///
/// The forward pass keeps only its delays at the start of every [`CHUNK`] samples; the
/// backward pass then runs chunk by chunk from the end, each chunk's forward outputs
/// recomputed from its checkpoint (the same operations from the same state, so the same
/// numbers), so that one chunk is held instead of a filtered copy of the record: the
/// forward pass costs twice, the memory is one chunk and a checkpoint of 40 delays per
/// chunk (0.08 bytes a sample).
///
/// Source: [`Butterworth::filtfilt`] (`scipy.signal.sosfiltfilt`, odd padding);
/// checkpointing as in reverse-mode differentiation (Griewank & Walther, *Evaluating
/// Derivatives*, 2nd ed., 2008, ch. 12).
fn filtfilt_chunks(
    bw: &Butterworth,
    x: [&[f64]; LANES],
    mut f: impl FnMut(usize, &[[f64; LANES]], Option<[f64; LANES]>),
) {
    let n = x.iter().map(|s| s.len()).min().unwrap_or(0);
    if n == 0 {
        return;
    }
    let p = bw.pad_len(n);
    let total = n + 2 * p;
    // The odd extension: p reflected samples each side.
    let ext = |i: usize| -> [f64; LANES] {
        std::array::from_fn(|l| {
            if i < p {
                2.0 * x[l][0] - x[l][p - i]
            } else if i < p + n {
                x[l][i - p]
            } else {
                2.0 * x[l][n - 1] - x[l][n - 2 - (i - p - n)]
            }
        })
    };
    // The chunk of the extension from index s: the record's own samples copied lane by lane
    // (no branch per value), the reflected ones by `ext`.
    let fill = |buf: &mut [[f64; LANES]], s: usize| {
        let (lo, hi) = (p.clamp(s, s + buf.len()), (p + n).clamp(s, s + buf.len()));
        for i in (s..lo).chain(hi..s + buf.len()) {
            buf[i - s] = ext(i);
        }
        if lo < hi {
            for (l, x) in x.iter().enumerate() {
                for (v, xi) in buf[lo - s..hi - s].iter_mut().zip(&x[lo - p..hi - p]) {
                    v[l] = *xi;
                }
            }
        }
    };
    // Per-section steady state under a constant input 1 (`sosfilt_zi`), as the filter has it.
    let sections = bw.sections();
    let mut scale = 1.0;
    let zi: Vec<[f64; 2]> = sections
        .iter()
        .map(|s| {
            let g = s.dc_gain();
            let z2 = s.b[2] - s.a[2] * g;
            let out = [scale * (s.b[1] - s.a[1] * g + z2), scale * z2];
            scale *= g;
            out
        })
        .collect();
    let mut buf = vec![[0.0; LANES]; CHUNK.min(total)];
    let mut z = Delays::steady(&zi, ext(0));
    let mut checkpoints = Vec::with_capacity(total.div_ceil(CHUNK));
    let mut last = [0.0; LANES];
    for s in (0..total).step_by(CHUNK) {
        checkpoints.push(z.clone());
        let chunk = &mut buf[..CHUNK.min(total - s)];
        fill(chunk, s);
        cascade(sections, &mut z, chunk, false);
        last = chunk[chunk.len() - 1];
    }
    let mut back = Delays::steady(&zi, last);
    let mut next = None;
    for (c, mut z) in checkpoints.into_iter().enumerate().rev() {
        let s = c * CHUNK;
        let chunk = &mut buf[..CHUNK.min(total - s)];
        fill(chunk, s);
        cascade(sections, &mut z, chunk, false);
        cascade(sections, &mut back, chunk, true);
        // The record's samples in this chunk (the padding dropped).
        let (lo, hi) = (s.max(p), (s + chunk.len()).min(p + n));
        if lo < hi {
            f(lo - p, &chunk[lo - s..hi - s], next);
            next = Some(chunk[lo - s]);
        }
    }
}

/// One pass of the filter's cascade over `buf` (forward, or backward when `reverse`), in
/// place, from and into the delays `z`. Lanes 0–3 run as one vector of four and lane 4
/// beside it: the same operations in the same order on every lane, so each lane's numbers
/// are those of a scalar pass to the bit, whatever the vector width; compiled for AVX-512
/// and AVX2 as well as the baseline and chosen at run time.
#[multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn cascade(sections: &[Biquad], z: &mut Delays, buf: &mut [[f64; LANES]], reverse: bool) {
    let z = &mut z.0;
    // A loop per direction around an inlined step (a closure would be compiled for the
    // baseline only, outside the target's features).
    if reverse {
        for v in buf.iter_mut().rev() {
            step(sections, z, v);
        }
    } else {
        for v in buf.iter_mut() {
            step(sections, z, v);
        }
    }
}

/// One sample `v` through every section of the cascade, updating the delays `z`.
#[inline(always)]
fn step(sections: &[Biquad], z: &mut [([[f64; 4]; 2], [f64; 2])], v: &mut [f64; LANES]) {
    let (mut q, mut w) = ([v[0], v[1], v[2], v[3]], v[4]);
    for (s, (zq, zw)) in sections.iter().zip(z.iter_mut()) {
        let y: [f64; 4] = std::array::from_fn(|l| s.b[0] * q[l] + zq[0][l]);
        zq[0] = std::array::from_fn(|l| s.b[1] * q[l] - s.a[1] * y[l] + zq[1][l]);
        zq[1] = std::array::from_fn(|l| s.b[2] * q[l] - s.a[2] * y[l]);
        q = y;
        let yw = s.b[0] * w + zw[0];
        zw[0] = s.b[1] * w - s.a[1] * yw + zw[1];
        zw[1] = s.b[2] * w - s.a[2] * yw;
        w = yw;
    }
    *v = [q[0], q[1], q[2], q[3], w];
}

/// Gram matrix `[C y O]ᵀ[C y O]` ([`GRAM`]²) of the base columns `C`, the voltage `y` and
/// the offset columns `O` over every interval of the applied voltage, from a zero-phase
/// low-passed copy of each log. One Gram serves every candidate `n_p` and both motor kinds.
///
/// # Errors
/// Those of [`applied_voltage`](crate::pmsm::model::interval::applied_voltage) and of the filter design.
pub(crate) fn scan_gram(views: &[DqView<'_>], input: VoltageInput) -> Result<DMatrix<f64>> {
    let mut grams = scan_grams(views, input, &[IDENTITY])?;
    Ok(grams.swap_remove(0))
}

/// The lanes `[u_d, u_q, i_d, i_q]` as the log gives them.
pub(crate) const IDENTITY: [usize; 4] = [0, 1, 2, 3];

/// [`scan_gram`] of the logs with their voltage and current channels relabelled, one Gram
/// per permutation of `lanes`: the Gram of permutation `π` is that of logs whose
/// `[u_d, u_q, i_d, i_q]` are the given `[x_π0, x_π1, x_π2, x_π3]` (the speed kept), to the
/// bit (the filter does the same operations on every lane, and each Gram sums its
/// intervals in the same order), from one filtering of each log: the column checks' swapped
/// hypotheses without a scan of their own.
///
/// # Errors
/// Those of [`scan_gram`].
pub(crate) fn scan_grams(
    views: &[DqView<'_>],
    input: VoltageInput,
    lanes: &[[usize; 4]],
) -> Result<Vec<DMatrix<f64>>> {
    let mut g = vec![[[0.0; GRAM]; GRAM]; lanes.len()];
    let relabel = |v: &[f64; LANES], p: &[usize; 4]| [v[p[0]], v[p[1]], v[p[2]], v[p[3]], v[4]];
    let mut permuted = Vec::new();
    for v in views {
        // n_p only scales the angle advance of a reference input; 1 is used for the scan.
        let (u_d, u_q) = driving_voltage(v, 1, input)?;
        // A zero-phase low-pass at 5 % of the sample rate keeps current noise out of di/dt
        // (MODEL.md §5: the derivative regressor is errors-in-variables).
        let h = v.h();
        let filter = Butterworth::try_new(SCAN_FILTER_ORDER, SCAN_CUTOFF / h, h)?;
        let turning = TURNING * v.w_m().iter().fold(0.0f64, |m, w| m.max(w.abs()));
        filtfilt_chunks(&filter, [&u_d, &u_q, v.i_d(), v.i_q(), v.w_m()], |_, chunk, next| {
            for (g, p) in g.iter_mut().zip(lanes) {
                let chunk = if *p == IDENTITY {
                    chunk
                } else {
                    permuted.clear();
                    permuted.extend(chunk.iter().map(|v| relabel(v, p)));
                    &permuted[..]
                };
                let cross = *p == IDENTITY;
                add_intervals(g, h, turning, cross, chunk);
                if let (Some(a), Some(b)) = (chunk.last(), next) {
                    if cross {
                        add_interval::<9>(g, h, turning, a, &b);
                    } else {
                        add_interval::<PLAIN>(g, h, turning, a, &relabel(&b, p));
                    }
                }
            }
        });
    }
    Ok(g.iter()
        .map(|g| DMatrix::from_fn(GRAM, GRAM, |a, b| if a <= b { g[a][b] } else { g[b][a] }))
        .collect())
}

/// Adds the d and q rows of every interval between consecutive samples of `chunk` (the
/// filtered `[u_d, u_q, i_d, i_q, w_m]`, sample time `h` \[s\]; offset columns above the
/// speed `turning`; the [`CROSS`] columns where `cross`) to the Gram `g`, in order.
#[multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn add_intervals(g: &mut [[f64; GRAM]; GRAM], h: f64, turning: f64, cross: bool, chunk: &[[f64; LANES]]) {
    // A local copy the compiler can hold in registers.
    let mut sums = *g;
    let pairs = chunk.iter().zip(chunk.iter().skip(1));
    if cross {
        pairs.for_each(|(a, b)| add_interval::<9>(&mut sums, h, turning, a, b));
    } else {
        pairs.for_each(|(a, b)| add_interval::<PLAIN>(&mut sums, h, turning, a, b));
    }
    *g = sums;
}

/// Adds the d and q rows of the interval from sample `a` to sample `b` to the Gram `g`: the
/// interval means of the current and the speed, the current's change over `h`, the
/// voltage of `a`, and the offset columns where the mean speed exceeds `turning` \[rad/s\];
/// the first `K` entries of each row ([`PLAIN`], or 9 with the cross columns).
#[inline(always)]
fn add_interval<const K: usize>(
    g: &mut [[f64; GRAM]; GRAM],
    h: f64,
    turning: f64,
    a: &[f64; LANES],
    b: &[f64; LANES],
) {
    let [ud, uq, id0, iq0, w0] = *a;
    let [_, _, id1, iq1, w1] = *b;
    let (i_d, i_q) = (0.5 * (id0 + id1), 0.5 * (iq0 + iq1));
    let (di_d, di_q) = ((id1 - id0) / h, (iq1 - iq0) / h);
    let w = 0.5 * (w0 + w1);
    let on = if w.abs() > turning { 1.0 } else { 0.0 };
    let d = [i_d, di_d, -w * i_q, ud, on, on * w, 1.0 - on, di_q, w * i_d];
    add_products::<K>(g, &D_COLUMNS, &d);
    add_products::<K>(g, &Q_COLUMNS, &[i_q, w * i_d, di_q, SQRT_2_3 * w, uq, on, 1.0 - on, di_d, w * i_q]);
}

/// Adds the products `r_a r_b` of a row's first `K` entries `r` (at base columns `at`) to
/// the upper triangle of `g`.
#[inline(always)]
fn add_products<const K: usize>(g: &mut [[f64; GRAM]; GRAM], at: &[usize; 9], r: &[f64; 9]) {
    for a in 0..K {
        for b in a..K {
            g[at[a]][at[b]] += r[a] * r[b];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every lane is `Butterworth::filtfilt` of its signal to the bit (the cascade's vector
    /// of four and its fifth lane included), for lengths around the padding.
    #[test]
    fn lanes_are_filtfilt_to_the_bit() {
        let h = 1e-4;
        let bw = Butterworth::try_new(SCAN_FILTER_ORDER, SCAN_CUTOFF / h, h).unwrap();
        // Around a chunk boundary (p the padding): a last chunk that holds the record's end
        // and the padding, or the padding after it only.
        let p = bw.pad_len(CHUNK);
        let edges = [CHUNK - 2 * p + 1, CHUNK - p - 1, CHUNK - p, CHUNK - p + 1, CHUNK];
        let sizes = [2, 7, 40, 1000, 5003, 2 * CHUNK - 30, 3 * CHUNK + 17].into_iter().chain(edges);
        for n in sizes {
            let signals: Vec<Vec<f64>> = (0..LANES)
                .map(|l| {
                    (0..n)
                        .map(|k| ((k * (l + 3)) as f64 * 0.013).sin() * (l as f64 + 0.5) + 0.1 * l as f64)
                        .collect()
                })
                .collect();
            let x: [&[f64]; LANES] = std::array::from_fn(|l| signals[l].as_slice());
            // The chunks, from the end, each followed by the next one's first sample.
            let mut lanes: Vec<[f64; LANES]> = Vec::new();
            let mut expect_next: Option<[f64; LANES]> = None;
            filtfilt_chunks(&bw, x, |k0, chunk, next| {
                assert_eq!(k0 + chunk.len(), n - lanes.len(), "n = {n}: chunks in reverse order");
                assert_eq!(next, expect_next, "n = {n}: the sample after chunk {k0}");
                expect_next = chunk.first().copied();
                lanes.splice(0..0, chunk.iter().copied());
            });
            assert_eq!(lanes.len(), n);
            for (l, s) in signals.iter().enumerate() {
                let direct = bw.filtfilt(s);
                let got: Vec<f64> = lanes.iter().map(|v| v[l]).collect();
                assert!(
                    got.iter().zip(&direct).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "lane {l}, n = {n}"
                );
            }
        }
        filtfilt_chunks(&bw, [&[]; LANES], |_, _, _| panic!("no samples, no chunk"));
    }
}
