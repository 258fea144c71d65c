//! Goodness-of-fit metrics of simulated against measured outputs.
//!
//! Sources: Ljung, *System Identification*, 2nd ed.: NRMSE fit (as MATLAB's `compare`),
//! 16.4 (FPE, AIC; Akaike 1969, 1974), BIC (Schwarz 1978), 16.6 (residual whiteness: the
//! normalised autocorrelation `r(τ)` lies within `±1.96/√N` for white residuals at the 95 %
//! level).
//!
//! Outputs are row-major `N × n_y` (`y[k n_y + i]` = output i at sample k), as the
//! estimator and [`crate::simulate::simulate`] give them.

use crate::error::{Error, Result};
use crate::estimate::LagSums;
use serde::{Deserialize, Serialize};

/// Residual whiteness of one output: normalised autocorrelation at lags `1..=max_lag`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Whiteness {
    /// `r(τ) = Σ_k e_k e_{k+τ} / Σ_k e_k²` for τ = 1..=max_lag, length max_lag.
    pub autocorrelation: Vec<f64>,
    /// 95 % bound `1.96/√N` for white residuals.
    pub bound: f64,
    /// Fraction of lags with `|r(τ)|` beyond the bound (about 0.05 for white residuals).
    pub fraction_outside: f64,
}

impl Whiteness {
    /// Ljung–Box portmanteau statistic `Q = N (N + 2) Σ_τ r(τ)²/(N − τ)` over the lags held,
    /// for `n` residual samples (Ljung & Box, *Biometrika* 65 (1978) 297–303); χ² with as
    /// many degrees of freedom as lags for white residuals.
    pub fn ljung_box(&self, n: usize) -> f64 {
        let n = n as f64;
        let sum: f64 =
            self.autocorrelation.iter().enumerate().map(|(k, r)| r * r / (n - (k + 1) as f64).max(1.0)).sum();
        n * (n + 2.0) * sum
    }

    /// The 1 % critical value of [`ljung_box`](Self::ljung_box): the 0.99 quantile of χ²
    /// with as many degrees of freedom as lags (Wilson–Hilferty cube-root approximation,
    /// within 0.1 % from 10 degrees of freedom; Johnson, Kotz & Balakrishnan, *Continuous
    /// Univariate Distributions* 1, 18.5); 0 without lags.
    pub fn ljung_box_critical(&self) -> f64 {
        let k = self.autocorrelation.len() as f64;
        if k == 0.0 {
            return 0.0;
        }
        const Z99: f64 = 2.326_347_874_040_841;
        let c = 2.0 / (9.0 * k);
        k * (1.0 - c + Z99 * c.sqrt()).powi(3)
    }

    /// Whether the residuals pass the whiteness test at the 1 % level
    /// ([`ljung_box`](Self::ljung_box) ≤ [`ljung_box_critical`](Self::ljung_box_critical)),
    /// for `n` samples.
    pub fn is_white(&self, n: usize) -> bool {
        self.ljung_box(n) <= self.ljung_box_critical()
    }
}

/// Metrics of one comparison of simulated against measured outputs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Output names, length n_y.
    pub outputs: Vec<String>,
    /// NRMSE fit per output `100 (1 − ‖y − ŷ‖/‖y − ȳ‖)` \[%\], length n_y.
    pub fit_percent: Vec<f64>,
    /// RMS residual per output \[output unit\], length n_y.
    pub rms_residual: Vec<f64>,
    /// Mean squared residual over all outputs, `E²/(N n_y)`.
    pub mse: f64,
    /// Akaike's final prediction error `V (1 + d/M)/(1 − d/M)` with `V = E²/M`,
    /// `M = N n_y` residuals and d parameters (∞ when d ≥ M).
    pub fpe: f64,
    /// `M ln(E²/M) + 2d`.
    pub aic: f64,
    /// `M ln(E²/M) + d ln M`.
    pub bic: f64,
    /// Residual whiteness per output, length n_y.
    pub whiteness: Vec<Whiteness>,
    /// Samples per output N.
    pub samples: usize,
}

/// NRMSE fit `100 (1 − √(SSE/SST))` \[%\] from the residual sum of squares and the sum of
/// squares about the mean; NaN for a constant output (SST = 0).
pub fn fit_percent(sse: f64, sst: f64) -> f64 {
    if sst > 0.0 { 100.0 * (1.0 - (sse / sst).sqrt()) } else { f64::NAN }
}

/// Akaike's final prediction error `V (1 + d/M)/(1 − d/M)`, `V = SSE/M`, for M residuals
/// and d parameters (∞ when d ≥ M).
pub fn fpe(sse: f64, m: usize, d: usize) -> f64 {
    let (m, d, v) = (m as f64, d as f64, sse / m as f64);
    if d < m { v * (1.0 + d / m) / (1.0 - d / m) } else { f64::INFINITY }
}

/// Akaike's information criterion `M ln(SSE/M) + 2d` (Gaussian, constants dropped).
pub fn aic(sse: f64, m: usize, d: usize) -> f64 {
    m as f64 * (sse / m as f64).ln() + 2.0 * d as f64
}

/// Schwarz's Bayesian information criterion `M ln(SSE/M) + d ln M`.
pub fn bic(sse: f64, m: usize, d: usize) -> f64 {
    m as f64 * (sse / m as f64).ln() + d as f64 * (m as f64).ln()
}

/// Metrics of `y_hat` against `y` (both row-major `N × n_y`, n_y = `outputs.len()`), for a
/// model with `n_params` estimated parameters; whiteness up to lag `max_lag` (clipped to
/// N − 1).
///
/// # Errors
/// [`Error::InvalidOption`] when the lengths disagree or are zero, or a value is not
/// finite.
pub fn metrics(
    outputs: &[String],
    y: &[f64],
    y_hat: &[f64],
    n_params: usize,
    max_lag: usize,
) -> Result<Metrics> {
    let ny = outputs.len();
    let bad = |reason: String| Error::InvalidOption { option: "outputs".into(), reason };
    if ny == 0 || y.is_empty() || y.len() != y_hat.len() || !y.len().is_multiple_of(ny) {
        return Err(bad(format!(
            "{} measured and {} simulated values for {ny} outputs",
            y.len(),
            y_hat.len()
        )));
    }
    if let Some(k) = y.iter().chain(y_hat).position(|v| !v.is_finite()) {
        return Err(bad(format!("value {k} of the outputs is not finite")));
    }
    let n = y.len() / ny;
    let column = |v: &[f64], i: usize| (0..n).map(|k| v[k * ny + i]).collect::<Vec<f64>>();
    let (mut fit_percent, mut rms_residual, mut whiteness) = (Vec::new(), Vec::new(), Vec::new());
    let mut sse_total = 0.0;
    for i in 0..ny {
        let (yi, hi) = (column(y, i), column(y_hat, i));
        let e: Vec<f64> = yi.iter().zip(&hi).map(|(a, b)| a - b).collect();
        let sse: f64 = e.iter().map(|v| v * v).sum();
        let mean = yi.iter().sum::<f64>() / n as f64;
        let sst: f64 = yi.iter().map(|v| (v - mean).powi(2)).sum();
        fit_percent.push(self::fit_percent(sse, sst));
        rms_residual.push((sse / n as f64).sqrt());
        whiteness.push(self::whiteness(&[&e], max_lag));
        sse_total += sse;
    }
    let m = n * ny;
    Ok(Metrics {
        outputs: outputs.to_vec(),
        fit_percent,
        rms_residual,
        mse: sse_total / m as f64,
        fpe: fpe(sse_total, m, n_params),
        aic: aic(sse_total, m, n_params),
        bic: bic(sse_total, m, n_params),
        whiteness,
        samples: n,
    })
}

/// Normalised autocorrelation at lags `1..=max_lag` of residuals recorded in `segments`
/// (one per experiment; lags never cross from one segment to the next), about their pooled
/// mean, with the 95 % whiteness bound `1.96/√N` (N: all samples; max_lag clipped to the
/// longest segment − 1). The numbers of [`whiteness_of`] the segments' [`LagSums`].
pub fn whiteness(segments: &[&[f64]], max_lag: usize) -> Whiteness {
    // Clipped first: no sums are kept for lags no segment has.
    let max_lag = max_lag.min(segments.iter().map(|s| s.len()).max().unwrap_or(0).saturating_sub(1));
    whiteness_of(&segments.iter().map(|s| LagSums::of(s, max_lag)).collect::<Vec<_>>())
}

/// [`whiteness`] from each segment's lag sums, as a fit's statistics stream them
/// ([`crate::estimate::problem::Sums::lag_sums`]) instead of keeping the residuals: lags
/// `1..=max_lag`, max_lag the smallest the sums hold, clipped to the longest segment − 1
/// (Ljung 1999, 16.6).
pub fn whiteness_of(segments: &[LagSums]) -> Whiteness {
    let n: usize = segments.iter().map(LagSums::n).sum();
    let mean = segments.iter().map(LagSums::total).sum::<f64>() / n.max(1) as f64;
    let held = segments.iter().map(LagSums::max_lag).min().unwrap_or(0);
    let lags = held.min(segments.iter().map(LagSums::n).max().unwrap_or(0).saturating_sub(1));
    let r0: f64 = segments.iter().map(|s| s.centred(0, mean)).sum();
    let autocorrelation: Vec<f64> = (1..=lags)
        .map(|tau| {
            let r: f64 = segments.iter().filter(|s| s.n() > tau).map(|s| s.centred(tau, mean)).sum();
            if r0 > 0.0 { r / r0 } else { 0.0 }
        })
        .collect();
    let bound = 1.96 / (n as f64).sqrt();
    let outside = autocorrelation.iter().filter(|r| r.abs() > bound).count();
    Whiteness {
        fraction_outside: if lags > 0 { outside as f64 / lags as f64 } else { 0.0 },
        autocorrelation,
        bound,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfect_fit_and_known_values() {
        let names = vec!["a".to_string()];
        let y = [1.0, 2.0, 3.0, 4.0];
        let m = metrics(&names, &y, &y, 1, 2).unwrap();
        assert_eq!(m.fit_percent, vec![100.0]);
        assert_eq!(m.mse, 0.0);
        // ŷ = ȳ gives a fit of 0 %.
        let m = metrics(&names, &y, &[2.5; 4], 1, 2).unwrap();
        assert!(m.fit_percent[0].abs() < 1e-12);
        assert!((m.mse - 1.25).abs() < 1e-12);
        assert!((m.fpe - 1.25 * (1.0 + 0.25) / (1.0 - 0.25)).abs() < 1e-12);
        assert!(metrics(&names, &y, &[1.0; 3], 1, 2).is_err());
    }

    /// A lag count beyond the data is clipped before any sums are kept (no overflow, no
    /// huge allocation): the lags the longest segment has.
    #[test]
    fn whiteness_clips_the_lags_to_the_data() {
        let e: Vec<f64> = (0..40).map(|k| (k as f64 * 0.9).sin()).collect();
        for max_lag in [39, 1_000_000_000, usize::MAX] {
            let w = whiteness(&[&e[..30], &e[30..]], max_lag);
            assert_eq!(w.autocorrelation.len(), 29, "max_lag {max_lag}");
        }
        assert_eq!(whiteness(&[&e], usize::MAX), whiteness(&[&e], 39));
    }

    /// The Ljung–Box test: white noise passes, an AR(1) sequence does not; the critical
    /// value is χ²'s 0.99 quantile (scipy.stats.chi2.ppf(0.99, 25) = 44.314).
    #[test]
    fn ljung_box_tells_white_from_coloured() {
        let mut rng = crate::estimate::test_rng::Xorshift::new(0x2545_f491_4f6c_dd1d);
        let mut next = || rng.uniform() - 0.5;
        let white: Vec<f64> = (0..20_000).map(|_| next()).collect();
        let mut x = 0.0;
        let ar: Vec<f64> = white
            .iter()
            .map(|e| {
                x = 0.3 * x + e;
                x
            })
            .collect();
        let w = whiteness(&[&white], 25);
        assert!((w.ljung_box_critical() - 44.314).abs() < 0.05, "{}", w.ljung_box_critical());
        assert!(w.is_white(white.len()), "Q = {}", w.ljung_box(white.len()));
        let c = whiteness(&[&ar], 25);
        assert!(!c.is_white(ar.len()), "Q = {}", c.ljung_box(ar.len()));
    }

    /// The one-sweep lag products are the per-lag dot products to the bit, for lengths
    /// around the lane and tile sizes and lags up to the length.
    #[test]
    fn lagged_dots_match_dot_per_lag() {
        use crate::estimate::lagged_dots;
        use crate::estimate::problem::dot;
        let v: Vec<f64> = (0..5000).map(|k| ((k * 7919) % 1013) as f64 / 97.0 - 5.0).collect();
        for n in [0, 1, 7, 8, 9, 30, 2047, 2048, 2049, 4100, 5000] {
            let s = &v[..n];
            let got = lagged_dots(s, 25);
            assert_eq!(got.len(), 26.min(n.max(1)), "n = {n}");
            for (tau, g) in got.iter().enumerate() {
                let want = dot(&s[..n - tau], &s[tau..]);
                assert_eq!(g.to_bits(), want.to_bits(), "n = {n}, τ = {tau}");
            }
        }
    }

    #[test]
    fn alternating_residuals_are_not_white() {
        let e: Vec<f64> = (0..200).map(|k| if k % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let w = whiteness(&[&e], 10);
        assert!((w.autocorrelation[0] + 1.0).abs() < 0.01);
        assert_eq!(w.fraction_outside, 1.0);
        // Split in two segments, the lag-1 products across the cut are left out.
        let w2 = whiteness(&[&e[..100], &e[100..]], 10);
        assert!((w2.autocorrelation[0] + 198.0 / 200.0).abs() < 1e-12, "{}", w2.autocorrelation[0]);
    }
}
