//! Which noise an output-error fit's residuals point to: noise on the measured current
//! leaves the simulated current's residual white; noise on the logged voltage (an input of
//! the model) colours it, since the model filters it, while the inverse model's voltage
//! error (`spm::inverse`) holds that noise unfiltered, white. Output error is then biased
//! (errors in variables; Söderström, *Automatica* 43 (2007) 939–958) and the report names
//! the instrumental-variable method, which is not.

use crate::estimate::Warning;
use crate::estimate::metrics;
use crate::estimate::problem::{LagStream, WHITENESS_LAGS};
use crate::model::GreyBoxModel;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::C64;
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::model::spm::PmsmSpm;

/// Noise on the logged voltage this small against its RMS value (rounding to a few
/// digits, say) is not worth a word.
pub const NEGLIGIBLE_VOLTAGE_NOISE: f64 = 1e-4;

/// The inverse model's voltage errors at θ over every log: their sum of squares, the
/// voltages' sum of squares, how many periods, and the errors' whiteness per axis.
struct VoltageErrors {
    sse: f64,
    suu: f64,
    n: usize,
    whiteness: [metrics::Whiteness; 2],
}

/// [`VoltageErrors`] of an SPM model at θ = (r_s, l_s, k_e); `None` for a log the inverse
/// model cannot read.
fn voltage_errors(views: &[DqView<'_>], setup: PmsmSetup, theta: &[f64]) -> Option<VoltageErrors> {
    let model = PmsmSpm::from_setup(setup);
    let (mut sse, mut suu, mut n) = (0.0, 0.0, 0usize);
    let mut lags = [Vec::new(), Vec::new()];
    for v in views {
        let inputs = model.prepare(v.experiment()).ok()?;
        let c = model.coefficients(theta, &inputs).ok()?;
        let i = |k: usize| C64::new(v.i_d()[k], v.i_q()[k]);
        let mut streams = [LagStream::new(WHITENESS_LAGS), LagStream::new(WHITENESS_LAGS)];
        for k in 0..v.len().saturating_sub(1) {
            let inv = model.inverse_step(&c, &inputs, k);
            let eps = inv.u - inv.voltage(i(k), i(k + 1)).0;
            streams[0].push(&[eps.re]);
            streams[1].push(&[eps.im]);
            sse += eps.norm_sqr();
            suu += inv.u.norm_sqr();
            n += 1;
        }
        for (all, s) in lags.iter_mut().zip(streams) {
            all.push(s.finish());
        }
    }
    Some(VoltageErrors { sse, suu, n, whiteness: lags.map(|l| metrics::whiteness_of(&l)) })
}

/// The white noise on the logged voltage, σ \[V\] per axis, read off the inverse model's
/// voltage errors ε at θ of an SPM model (module documentation) by their autocovariances
/// γ₀ … γ₃. ε holds the voltage noise (white, σ²), the currents' noise through the difference
/// `(L/h)(n[k+1] − a n[k])` (lags 0 and 1 only, `γ₁ = −a c² σ_n²` with `a ≈ 1`) and the
/// model's slow error (a smooth autocovariance `S (1 − c k² + …)`), so
/// `σ² ≈ γ₀ + 2γ₁ − 5γ₂ + 2γ₃`, which is exact for the first two and cancels the third to
/// its quartic term (a Gaussian-shaped error of correlation time T leaves `10.5 S/T⁴`).
/// Returns `(σ, √γ₀, rms)`: the noise, the errors' RMS value and the voltages' per axis
/// \[V\]; `None` for a log the inverse model cannot read.
pub(crate) fn voltage_noise(
    views: &[DqView<'_>],
    setup: PmsmSetup,
    theta: &[f64],
) -> Option<(f64, f64, f64)> {
    let v = voltage_errors(views, setup, theta)?;
    let (gamma_0, rho) = autocorrelations(&v);
    let m = (2 * v.n.max(1)) as f64;
    Some((white_power(gamma_0, rho).sqrt(), gamma_0.sqrt(), (v.suu / m).sqrt()))
}

/// The inverse model's voltage errors' variance γ₀ \[V²\] and their autocorrelations at
/// lags 1, 2, 3, the axes' mean (the whiteness holds lags 1, 2, …).
fn autocorrelations(v: &VoltageErrors) -> (f64, [f64; 3]) {
    let gamma_0 = v.sse / (2 * v.n.max(1)) as f64;
    let rho = |lag: usize| {
        v.whiteness.iter().map(|w| w.autocorrelation.get(lag - 1).copied().unwrap_or(0.0)).sum::<f64>() / 2.0
    };
    (gamma_0, [rho(1), rho(2), rho(3)])
}

/// The white part σ² = γ₀ + 2γ₁ − 5γ₂ + 2γ₃ of the errors (at least 0; [`voltage_noise`])
/// from γ₀ and the autocorrelations at lags 1, 2, 3.
fn white_power(gamma_0: f64, rho: [f64; 3]) -> f64 {
    (gamma_0 * (1.0 + 2.0 * rho[0] - 5.0 * rho[1] + 2.0 * rho[2])).max(0.0)
}

/// The white noise powers of the logged voltage, σ_u² \[V²\] per axis as
/// [`voltage_noise`] reads it, and of the measured currents, σ_i² \[A²\], from the errors'
/// lag-1 autocovariance `γ₁ = −a c² σ_i²` (the module's difference `c (n[k+1] − a n[k])`,
/// `c = r_s/(1 − a)`, the inverse of the current channel's gain, ≈ L/h), at θ of an SPM
/// model and the current channel's pole `a` ∈ (0, 1); `None` for a log the inverse model
/// cannot read.
pub(crate) fn noise_powers(
    views: &[DqView<'_>],
    setup: PmsmSetup,
    theta: &[f64],
    a: f64,
) -> Option<(f64, f64)> {
    let v = voltage_errors(views, setup, theta)?;
    let (gamma_0, rho) = autocorrelations(&v);
    let c = theta[0] / (1.0 - a);
    let sigma_i2 = (-gamma_0 * rho[0]).max(0.0) / (a * c * c);
    Some((white_power(gamma_0, rho), sigma_i2))
}

/// A notice (code `input_noise`) when the inverse model's voltage errors at θ = (r_s, l_s,
/// k_e) of an SPM model driven by the terminal voltage are white in every log and not
/// negligible, for a fit whose own residuals are not white; `None` otherwise, or for a log
/// the inverse model cannot read.
pub(crate) fn input_noise_notice(views: &[DqView<'_>], setup: PmsmSetup, theta: &[f64]) -> Option<Warning> {
    let VoltageErrors { sse, suu, n, whiteness } = voltage_errors(views, setup, theta)?;
    let sigma = (sse / (2 * n.max(1)) as f64).sqrt();
    let rms = (suu / (2 * n.max(1)) as f64).sqrt();
    (whiteness.iter().all(|w| w.is_white(n)) && sigma > NEGLIGIBLE_VOLTAGE_NOISE * rms).then(|| {
        Warning::notice(
            "input_noise",
            format!(
                "the current residuals are coloured but the voltage equations' errors are white (σ ≈ {sigma:.3e} V \
                 per axis): noise on the logged voltage, which output error filters into its residuals and which \
                 biases it (errors in variables); --method iv (instrumental variables on the inverse model) is \
                 not biased by it"
            ),
        )
    })
}
