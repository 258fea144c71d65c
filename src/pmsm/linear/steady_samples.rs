//! The steady samples of a slow log ([`super::steady`]): the current noise from the
//! second differences, and the samples whose stencil `k − 2 … k + 2` is smooth.

/// Fewest samples smooth across `k − 2 … k + 2` for the stencil rule of [`steady_indices`]
/// (else the rule at k alone): the stencils cost the samples at a plateau's ends, and a log
/// whose plateaus are a few samples long keeps too few, on too few operating points. Every
/// 1500th–2500th row of an 8 s drive-simulator log (33–54 rows) kept 6–8 stencils, all on
/// plateaus, whose equations did not determine the parameters (exact fits with intervals of
/// zero width, R_s from −15 to 62 Ω); the rule at k alone kept 6–11 samples, with honest
/// `undetermined` intervals at the 1500th and 2000th rows. 128
/// is also the fewest steady samples whose blocks hold more than one sample (32 batches of
/// 4 blocks, [`super::steady_solve`]).
pub(super) const FEWEST_STENCILS: usize = 128;

/// z of the 20 % quantile of |N(0, 1)|: `P(|Z| ≤ 0.2533) = 0.2`.
const Q20_ABS_NORMAL: f64 = 0.2533;

/// Noise σ \[A\] of a sampled current from the lower 20 % quantile of its second
/// differences `|x[k+1] − 2 x[k] + x[k−1]|` (standard deviation `√6 σ` for white noise).
pub(super) fn noise_sigma(x: &[f64]) -> f64 {
    let mut d: Vec<f64> =
        x.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).abs()).filter(|v| v.is_finite()).collect();
    if d.is_empty() {
        return 0.0;
    }
    let k = d.len() / 5;
    let (_, q, _) = d.select_nth_unstable_by(k, f64::total_cmp);
    *q / (Q20_ABS_NORMAL * SQRT_6)
}

/// `√6`: the standard deviation of a second difference of unit white noise.
pub(super) const SQRT_6: f64 = 2.449_489_742_783_178;

/// Indices k of the steady samples of one experiment: samples `k ± 2` exist (the
/// instruments') and neither current's second difference exceeds its threshold at k − 1,
/// k and k + 1 (the whole stencil `k − 2 … k + 2` the equation and its instruments read is
/// one smooth stretch); where that leaves fewer than `fewest` samples, at k alone. Returns
/// the indices and the number of whole stencils (the indices' count when they are those).
pub(super) fn steady_indices(i_d: &[f64], i_q: &[f64], thr: [f64; 2], fewest: usize) -> (Vec<usize>, usize) {
    let n = i_d.len().min(i_q.len());
    let smooth: Vec<bool> = (0..n)
        .map(|k| {
            k > 0
                && k + 1 < n
                && [(i_d, thr[0]), (i_q, thr[1])]
                    .iter()
                    .all(|(x, t)| (x[k + 1] - 2.0 * x[k] + x[k - 1]).abs() <= *t)
        })
        .collect();
    let wide: Vec<usize> =
        (2..n.saturating_sub(2)).filter(|&k| smooth[k - 1] && smooth[k] && smooth[k + 1]).collect();
    match wide.len() >= fewest {
        true => {
            let stencils = wide.len();
            (wide, stencils)
        }
        false => ((2..n.saturating_sub(2)).filter(|&k| smooth[k]).collect(), wide.len()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ramp that starts at sample 10: the second difference exceeds the threshold only
    /// there, so the stencil rule leaves out 9, 10 and 11, the rule at k alone only 10, and
    /// a log with fewer whole stencils than asked for falls back to it.
    #[test]
    fn the_stencils_around_a_kink_are_not_steady() {
        let i_d: Vec<f64> = (0..30).map(|k| if k <= 10 { 0.0 } else { (k - 10) as f64 }).collect();
        let i_q = vec![1.0; 30];
        let (wide, stencils) = steady_indices(&i_d, &i_q, [0.5, 0.5], 5);
        assert_eq!(wide, (2..28).filter(|k| !(9..=11).contains(k)).collect::<Vec<_>>());
        assert_eq!(stencils, 23);
        let (narrow, stencils) = steady_indices(&i_d, &i_q, [0.5, 0.5], 24);
        assert_eq!(narrow, (2..28).filter(|&k| k != 10).collect::<Vec<_>>());
        assert_eq!(stencils, 23);
        // The same kink in i_q.
        let (wide, _) = steady_indices(&i_q, &i_d, [0.5, 0.5], 5);
        assert_eq!(wide.len(), 23);
    }
}
