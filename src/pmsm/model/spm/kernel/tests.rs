//! Tests of the block kernel's interval data.

use super::*;
use crate::pmsm::IntervalVoltage;
use crate::pmsm::model::interval::IntervalSource;

/// A block's interval data ([`IntervalSource::fill_intervals`]) are the per-sample ones
/// ([`IntervalSource::interval`]) to the bit, for both holds and both kinds of voltage, with
/// half angles on both sides of ±π/4 (the polynomial and the library's sine) in one block.
#[test]
fn block_interval_data_are_the_per_sample_ones() {
    let n = 300;
    // φ/2 = n_p ω_m h / 2 runs from −0.18 to 1.15 rad: past π/4 from ω_m ≈ 3927 rad/s.
    let w_m: Vec<f64> = (0..n).map(|k| (k as f64 - 40.0) * 22.0 + (k as f64 * 0.37).sin()).collect();
    let d: Vec<f64> = (0..n).map(|k| 50.0 * (k as f64 * 0.05).cos()).collect();
    let q: Vec<f64> = (0..n).map(|k| -20.0 + 3.0 * (k as f64 * 0.11).sin()).collect();
    let start: Vec<C64> = (0..n - 1).map(|k| C64::new(d[k] + 1.5, q[k] - 0.5)).collect();
    let voltages = [IntervalVoltage::Terminal(d.into(), q.into()), IntervalVoltage::Start(start)];
    for u in voltages {
        let inp = IntervalSource { h: 1e-4, n_p: 4.0, w_m: w_m.clone().into(), u };
        for hold in [VoltageHold::Dq, VoltageHold::Stator] {
            for k0 in [0, 37, n - 1 - 5] {
                let steps = BLOCK_LEN.min(n - 1 - k0);
                let mut buf = vec![0.0; INTERVAL_ARRAYS * BLOCK_LEN];
                let mut ch = buf.chunks_exact_mut(BLOCK_LEN).map(|c| &mut c[..steps]);
                let mut next = || ch.next().unwrap_or_default();
                let iv = IntervalData { w_m: next(), sin: next(), cos: next(), u_re: next(), u_im: next() };
                inp.fill_intervals(hold == VoltageHold::Stator, k0, iv);
                let col = |a: usize, t: usize| buf[a * BLOCK_LEN + t].to_bits();
                for t in 0..steps {
                    let ([s, c], w, u) = inp.interval(hold, k0 + t);
                    let want = [w, s, c, u.re, u.im].map(f64::to_bits);
                    let got = [col(0, t), col(1, t), col(2, t), col(3, t), col(4, t)];
                    assert_eq!(got, want, "{hold}, block at {k0}, interval {}", k0 + t);
                }
            }
        }
    }
}
