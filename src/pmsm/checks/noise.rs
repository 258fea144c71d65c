//! Which noise an output-error fit's residuals point to: noise on the measured current
//! leaves the simulated current's residual white; noise on the logged voltage (an input of
//! the model) colours it, since the model filters it, while the inverse model's voltage
//! error (`spm::inverse`) holds that noise unfiltered, white. Output error is then biased
//! (errors in variables; Söderström, *Automatica* 43 (2007) 939–958) and the report names
//! the instrumental-variable method, which is not.

use crate::estimate::Warning;
use crate::estimate::metrics;
use crate::estimate::problem::{LagStream, LagSums, WHITENESS_LAGS};
use crate::model::GreyBoxModel;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::C64;
use crate::pmsm::model::ipm::PmsmIpm;
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
    /// Per axis (IPM only): the errors' sum of squares, and the mean over the intervals of
    /// `b² (r_s² + ω_e² L_o²)`, with `b` the axis's gain and `L_o` the other axis's
    /// inductance: what the currents' noise of lag-1 autocovariance γ₁ leaves in the white
    /// part, `−γ₁` times it ([`current_leak`]). The SPM inverse leaves the same,
    /// `(r_s² + ω_e² l_s²) σ_i²`, which is not taken off: its estimate is that of the
    /// earlier releases (reports identical), and its logs' current noise is small beside
    /// the voltage noise it finds (0.03 A against 1 V on the servo logs).
    leak: Option<[(f64, f64); 2]>,
}

/// [`VoltageErrors`] at θ: of an SPM model for θ = (r_s, l_s, k_e), of an IPM model
/// ([`ipm_voltage_errors`]) for θ = (r_s, l_d, l_q, k_e); `None` for a log the model
/// cannot read or another length.
fn voltage_errors(views: &[DqView<'_>], setup: PmsmSetup, theta: &[f64]) -> Option<VoltageErrors> {
    match theta.len() {
        3 => spm_voltage_errors(views, setup, theta),
        4 => ipm_voltage_errors(views, setup, theta),
        _ => None,
    }
}

/// The running sums of [`VoltageErrors`] over the logs' intervals.
#[derive(Default)]
struct ErrorSums {
    sse: f64,
    suu: f64,
    n: usize,
    lags: [Vec<LagSums>; 2],
}

impl ErrorSums {
    /// Adds one log of `intervals` intervals, `interval(k)` giving interval k's voltage
    /// error ε (d, q) \[V\] and its voltage's squared magnitude \[V²\].
    fn add_log(&mut self, intervals: usize, mut interval: impl FnMut(usize) -> ([f64; 2], f64)) {
        let mut streams = [LagStream::new(WHITENESS_LAGS), LagStream::new(WHITENESS_LAGS)];
        for k in 0..intervals {
            let (eps, u2) = interval(k);
            streams[0].push(&[eps[0]]);
            streams[1].push(&[eps[1]]);
            self.sse += eps[0] * eps[0] + eps[1] * eps[1];
            self.suu += u2;
            self.n += 1;
        }
        for (all, s) in self.lags.iter_mut().zip(streams) {
            all.push(s.finish());
        }
    }

    /// The [`VoltageErrors`] of the logs added, with the IPM's `leak` sums.
    fn finish(self, leak: Option<[(f64, f64); 2]>) -> VoltageErrors {
        let Self { sse, suu, n, lags } = self;
        VoltageErrors { sse, suu, n, whiteness: lags.map(|l| metrics::whiteness_of(&l)), leak }
    }
}

/// [`VoltageErrors`] of an SPM model at θ = (r_s, l_s, k_e) by its exact inverse step;
/// `None` for a log the inverse model cannot read.
fn spm_voltage_errors(views: &[DqView<'_>], setup: PmsmSetup, theta: &[f64]) -> Option<VoltageErrors> {
    let model = PmsmSpm::from_setup(setup);
    let mut sums = ErrorSums::default();
    for v in views {
        let inputs = model.prepare(v.experiment()).ok()?;
        let c = model.coefficients(theta, &inputs).ok()?;
        let i = |k: usize| C64::new(v.i_d()[k], v.i_q()[k]);
        sums.add_log(v.len().saturating_sub(1), |k| {
            let inv = model.inverse_step(&c, &inputs, k);
            let eps = inv.u - inv.voltage(i(k), i(k + 1)).0;
            ([eps.re, eps.im], inv.u.norm_sqr())
        });
    }
    Some(sums.finish(None))
}

/// [`VoltageErrors`] of an IPM model at θ = (r_s, l_d, l_q, k_e), whose step has no
/// scalar inverse: each axis's one-step current error `i[k+1] − x⁺(θ, k, i[k])` of the
/// model's exact step, divided by that axis's gain from a held voltage to the current over
/// one interval, `b = (1 − e^{−h r_s/L})/r_s` with `L` the axis's inductance. The voltage's
/// white noise reaches the error through that gain (the frame's turn within an interval,
/// `ω_e h`, mixes the axes' noise, not its power, to first order), the currents' noise as
/// the SPM inverse's difference `(n[k+1] − a n[k])/b`, so [`voltage_noise`] reads both
/// models' errors alike. `None` for a log the model cannot read or a gain that is not
/// positive and finite.
fn ipm_voltage_errors(views: &[DqView<'_>], setup: PmsmSetup, theta: &[f64]) -> Option<VoltageErrors> {
    let model = PmsmIpm::from_setup(setup);
    let mut sums = ErrorSums::default();
    let mut axes = [(0.0, 0.0); 2];
    for v in views {
        let inputs = model.prepare(v.experiment()).ok()?;
        let c = model.coefficients(theta, &inputs).ok()?;
        let h = v.experiment().h();
        // The limit h/L at r_s = 0 (expm1 is exact to the last bit for small arguments).
        let gain = |l: f64| if theta[0] == 0.0 { h / l } else { -(-h * theta[0] / l).exp_m1() / theta[0] };
        let b = [gain(theta[1]), gain(theta[2])];
        if !b.iter().all(|b| b.is_finite() && *b > 0.0) {
            return None;
        }
        let (u_d, u_q) = v.terminal_voltage().ok()?;
        let (i_d, i_q, w_m) = (v.i_d(), v.i_q(), v.w_m());
        let n_p = f64::from(setup.n_p);
        let mut next = [0.0; 2];
        sums.add_log(v.len().saturating_sub(1), |k| {
            model.step(&c, &inputs, k, &[i_d[k], i_q[k]], &mut next);
            let eps = [(i_d[k + 1] - next[0]) / b[0], (i_q[k + 1] - next[1]) / b[1]];
            let w_e = n_p * w_m[k];
            for (axis, (e, l_o)) in eps.iter().zip([theta[2], theta[1]]).enumerate() {
                axes[axis].0 += e * e;
                axes[axis].1 += b[axis] * b[axis] * (theta[0] * theta[0] + w_e * w_e * l_o * l_o);
            }
            (eps, u_d[k] * u_d[k] + u_q[k] * u_q[k])
        });
    }
    let n = sums.n.max(1) as f64;
    Some(sums.finish(Some(axes.map(|(e2, l)| (e2, l / n)))))
}

/// The white noise on the logged voltage, σ \[V\] per axis, read off the inverse model's
/// voltage errors ε at θ of an SPM model, or an IPM model's ([`ipm_voltage_errors`]) for
/// θ of length 4 (module documentation) by their autocovariances
/// γ₀ … γ₃. ε holds the voltage noise (white, σ²), the currents' noise through the difference
/// `(L/h)(n[k+1] − a n[k])` (lags 0 and 1 only, `γ₁ = −a c² σ_n²` with `a ≈ 1`) and the
/// model's slow error (a smooth autocovariance `S (1 − c k² + …)`), so
/// `σ² ≈ γ₀ + 2γ₁ − 5γ₂ + 2γ₃`, which is exact for the first two and cancels the third to
/// its quartic term (a Gaussian-shaped error of correlation time T leaves `10.5 S/T⁴`).
/// For an IPM, what the currents' noise leaves there at speed is taken off first
/// ([`current_leak`]). σ is 0 where the white part is not above [`NOISE_SIGNIFICANCE_Z`]
/// standard errors of its estimator ([`white_power_se`]). Returns `(σ, √γ₀, rms)`: the
/// noise, the errors' RMS value and the voltages' per axis \[V\]; `None` for a log the
/// inverse model cannot read.
pub(crate) fn voltage_noise(
    views: &[DqView<'_>],
    setup: PmsmSetup,
    theta: &[f64],
) -> Option<(f64, f64, f64)> {
    let v = voltage_errors(views, setup, theta)?;
    let (gamma_0, rho) = autocorrelations(&v);
    let m = (2 * v.n.max(1)) as f64;
    let white = white_power(gamma_0, rho) - current_leak(&v);
    // Not told from zero: 0 (the estimator's own spread is the currents' noise, which can be
    // a hundred times the voltage's when the inductance is large against the sample time).
    let white = if white > NOISE_SIGNIFICANCE_Z * white_power_se(gamma_0, rho[0], m) { white } else { 0.0 };
    Some((white.sqrt(), gamma_0.sqrt(), (v.suu / m).sqrt()))
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

/// What the currents' noise leaves in an IPM's white part \[V²\] per axis (0 for an SPM,
/// whose [`VoltageErrors::leak`] is `None`):
/// the one-step error carries the current noise `n` as `n[k+1] − A n[k]`, whose lag-0 and
/// lag-1 terms `γ₀ + 2γ₁` cancel but for the part the step's resistance and cross-coupling
/// turn (`A ≈ I − h L⁻¹ (r_s + ω_e J L)`), `(r_s² + ω_e² L_o²) σ_n²` in the voltage
/// scale of [`ipm_voltage_errors`] with `σ_n² ≈ −γ₁ b²` of the axis (the two axes' current
/// noise taken equal, for `L_o` turns the other axis's into this one's): at speed the
/// currents' noise reads as voltage noise of `ω_e L_o σ_n`, which is not the logged
/// voltage's (0.65 A of current noise on the other simulator's IPM log read as 1.1 V).
fn current_leak(v: &VoltageErrors) -> f64 {
    let Some(axes) = v.leak else { return 0.0 };
    let n = v.n.max(1) as f64;
    axes.iter().zip(&v.whiteness).map(|((e2, leak), w)| minus_gamma_1(e2 / n, w) * leak).sum::<f64>() / 2.0
}

/// An axis's lag-1 autocovariance, negated and at least 0, `max(−γ₀ ρ₁, 0)` \[V²\], from
/// its errors' variance γ₀ and their whiteness (ρ₁ 0 where it holds no lag).
fn minus_gamma_1(gamma_0: f64, w: &metrics::Whiteness) -> f64 {
    (-gamma_0 * w.autocorrelation.first().copied().unwrap_or(0.0)).max(0.0)
}

/// Standard errors by which the white part of the voltage equations' errors (their
/// variance less what the currents' noise and the model's slow error explain, from their
/// autocorrelations at lags 1–3) must exceed zero to be taken as the voltage's noise; the
/// standard error is that of the estimator, by Bartlett's formula (docs/warnings.md,
/// `voltage_noise_bias`). One-sided, about 2.3 % of noise-free voltages pass it: the costs
/// are not alike, for a voltage noise missed leaves output error's bias with exit 0, while
/// one found falsely costs the variance of instrumental variables, which are unbiased
/// either way (or an exit 3 where their two holds then disagree). At 3, 1 V of voltage
/// noise with 0.03 A of current noise on 3-second exp3 logs was found in 70 of 80 (the
/// test `the_default_covers_the_truth_under_voltage_and_current_noise` asks for 72). The
/// other simulator's noisy IPM log (0.05 V of voltage noise, 0.65 A of current noise,
/// 67 000 samples) reads 1.15 V² at 0.9 standard errors (it sent a right output-error fit
/// to instrumental variables and exit 3 without the test); 1 V of voltage noise on the
/// shared IPM log reads about 1.2 V² at about 15.
pub const NOISE_SIGNIFICANCE_Z: f64 = 2.0;

/// The standard error \[V²\] of the white part `γ₀ (1 + 2ρ₁ − 5ρ₂ + 2ρ₃)` from `m`
/// errors (both axes) of variance γ₀ and lag-1 autocorrelation ρ = ρ₁, the currents' noise
/// making them a first-order moving average: by Bartlett's variances and covariances of
/// the estimated autocorrelations (Box, Jenkins & Reinsel, *Time Series Analysis*, 4th ed.,
/// 2008, 6.2.2), `m Var/γ₀² = 33 − 80ρ + 54ρ² + 40ρ³ + 16ρ⁴` (33 for white errors, 82.5 at
/// ρ = −½; the spread of 2000 simulated records of 20 000 samples was within 0.1 % of it at
/// ρ = −½ and 3 % above it for white errors).
fn white_power_se(gamma_0: f64, rho: f64, m: f64) -> f64 {
    let var = 33.0 + rho * (-80.0 + rho * (54.0 + rho * (40.0 + 16.0 * rho)));
    gamma_0 * (var.max(0.0) / m).sqrt()
}

/// The white part σ² = γ₀ + 2γ₁ − 5γ₂ + 2γ₃ of the errors (at least 0; [`voltage_noise`])
/// from γ₀ and the autocorrelations at lags 1, 2, 3.
fn white_power(gamma_0: f64, rho: [f64; 3]) -> f64 {
    (gamma_0 * (1.0 + 2.0 * rho[0] - 5.0 * rho[1] + 2.0 * rho[2])).max(0.0)
}

/// The white noise powers of the logged voltage, σ_u² \[V²\] per axis by
/// [`voltage_noise`]'s formula (without its significance test: a floor, not a finding), and
/// of the measured currents, σ_i² \[A²\], from the errors'
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

/// The white noise powers of an IPM model's inputs at θ = (r_s, l_d, l_q, k_e) per axis
/// (d, q): the logged voltage's σ_u² \[V²\], [`voltage_noise`]'s white part of that axis's
/// errors ([`ipm_voltage_errors`]) less what the currents' noise leaves there
/// ([`current_leak`]), without the significance test (a floor, not a finding); and the
/// measured currents' σ_i² \[A²\], the axes' mean of `−γ₁ b²/a` from each axis's lag-1
/// autocovariance `γ₁ = −a σ_i²/b²` (`a = e^{−h r_s/L}`, `b = (1 − a)/r_s` of the axis at
/// the logs' longest interval h). `None` for a log the inverse model cannot read or a pole
/// outside (0, 1).
pub(crate) fn ipm_noise_powers(
    views: &[DqView<'_>],
    setup: PmsmSetup,
    theta: &[f64; 4],
) -> Option<([f64; 2], f64)> {
    let v = ipm_voltage_errors(views, setup, theta)?;
    let axes = v.leak?;
    let n = v.n.max(1) as f64;
    let h = views.iter().map(|v| v.experiment().h()).fold(0.0, f64::max);
    let (mut sigma_u2, mut sigma_i2) = ([0.0; 2], 0.0);
    for (axis, ((e2, leak), w)) in axes.iter().zip(&v.whiteness).enumerate() {
        let a = (-h * theta[0] / theta[1 + axis]).exp();
        if !(a > 0.0 && a < 1.0) {
            return None;
        }
        let b = (1.0 - a) / theta[0];
        let rho = |lag: usize| w.autocorrelation.get(lag - 1).copied().unwrap_or(0.0);
        let gamma_0 = e2 / n;
        let g1 = minus_gamma_1(gamma_0, w);
        sigma_u2[axis] = (white_power(gamma_0, [rho(1), rho(2), rho(3)]) - g1 * leak).max(0.0);
        sigma_i2 += g1 * b * b / a / 2.0;
    }
    Some((sigma_u2, sigma_i2))
}

/// A notice (code `input_noise`) when the inverse model's voltage errors at θ = (r_s, l_s,
/// k_e) of an SPM model driven by the terminal voltage are white in every log and not
/// negligible, for a fit whose own residuals are not white; `None` otherwise, or for a log
/// the inverse model cannot read.
pub(crate) fn input_noise_notice(views: &[DqView<'_>], setup: PmsmSetup, theta: &[f64]) -> Option<Warning> {
    let VoltageErrors { sse, suu, n, whiteness, .. } = voltage_errors(views, setup, theta)?;
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
