//! The controller's phase-locked loop of a PWM fit: its bandwidth by search, the set of
//! bandwidths the log cannot tell from it, and whether the motor's estimates depend on
//! which of them the drive has.
//!
//! The loop places the frame the drive transforms its reference with (a sensored
//! controller's angle estimate, [`controller_frame`]). It is searched, not estimated with
//! the parameters, so its uncertainty is not in their covariance. Where the log pins it
//! (noise-free logs: the loss doubles a few per cent away) that does not matter; under
//! current noise the loss is flat over a wide range (0.05 A per phase on the shared 3 µs
//! log: the search's minimum scattered over 1560 … 6700 rad/s around the drive's 2224), and
//! a fit at one end of that range may hold the motor's parameters elsewhere than the other.
//! So the final fit is repeated at the ends of the range the likelihood-ratio test does not
//! reject, and estimates more than [`LOOP_AMBIGUOUS_Z`] standard errors apart make the fit
//! untrusted (`loop_ambiguous`), as two tied voltage holds do.
//!
//! [`controller_frame`]: crate::pmsm::model::interval::controller_frame

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::{FitResult, Warning, Weighting};
use crate::model::GreyBoxModel;
use crate::pmsm::fit::search::{SPEED_PLL_RANGE, golden_search};
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::pwm::PmsmPwm;

/// Standard errors by which a motor parameter's estimates at the ends of the loop's set
/// may differ from the fit's before the fit is untrusted (`loop_ambiguous`).
pub const LOOP_AMBIGUOUS_Z: f64 = 3.0;

/// Log-spaced bandwidths of the scan that finds the set.
const SET_SCAN: usize = 25;

/// χ²₁(0.95): the likelihood-ratio bound of the set.
const CHI2_1_95: f64 = 3.841;

/// The loop's search: the chosen input, a note, and the set of bandwidths the
/// likelihood-ratio test does not reject (`[lo, hi]` \[rad/s\], `None` when the logged
/// frame predicts better).
pub(crate) struct LoopSearch {
    pub input: VoltageInput,
    pub note: Option<String>,
    pub set: Option<[f64; 2]>,
}

/// The bandwidth of the controller's phase-locked loop by the lowest one-step loss of
/// `model` at `theta` (weighted by `weighting`) over [`SPEED_PLL_RANGE`] (a scan and a
/// golden-section search on its logarithm), or the logged angle and speed if those predict
/// better; and the bandwidths whose loss `V` the likelihood-ratio test does not reject,
/// `(V − V_min) n / V_min < χ²₁(0.95)` (`n` counted residuals; Ljung, *System
/// Identification*, 2nd ed., 16.4), over a log-spaced scan (none for the terminal voltage,
/// which has no controller's frame). Without `scan_set` (a nested fit, which runs no
/// checks) the set is the bandwidth found alone, and the scan is saved.
///
/// # Errors
/// Those of the model's `prepare` and [`PmsmPwm::sign_margins`].
pub(crate) fn search_speed_pll(
    experiments: &[Experiment],
    input: VoltageInput,
    theta: &[f64],
    weighting: &dyn Weighting,
    model: &dyn Fn(VoltageInput) -> Result<PmsmPwm>,
    scan_set: bool,
) -> Result<LoopSearch> {
    let VoltageInput::Reference { delay, advance, .. } = input else {
        return Ok(LoopSearch { input, note: None, set: None });
    };
    let at = |speed_pll: Option<f64>| VoltageInput::Reference { delay, advance, speed_pll };
    let counted = std::cell::Cell::new(0usize);
    let loss = |speed_pll: Option<f64>| -> Result<f64> {
        let m = model(at(speed_pll))?;
        let (mut sum, mut n) = (0.0, 0);
        for e in experiments {
            let margins = m.sign_margins(theta, &m.prepare(e)?)?;
            for (k, s) in margins.iter().enumerate() {
                let w = weighting.sample_weight(e, k);
                sum += w * s.residual.powi(2);
                n += usize::from(w > 0.0 && k > 0);
            }
        }
        counted.set(n);
        Ok(0.5 * sum)
    };
    let alpha = golden_search(SPEED_PLL_RANGE, true, |a| loss(Some(a)))?;
    let (with, logged) = (loss(Some(alpha))?, loss(None)?);
    let chosen = if with < logged { Some(alpha) } else { None };
    let note = format!(
        "the controller's frame: a phase-locked loop of {alpha:.1} rad/s on theta_m (one-step loss {with:.6e}) \
         against the logged angle and speed ({logged:.6e}): {}",
        if chosen.is_some() { "the loop" } else { "the logged" }
    );
    let set = match chosen {
        None => None,
        Some(alpha) if !scan_set => Some([alpha, alpha]),
        Some(alpha) => {
            let (lo, hi) = (SPEED_PLL_RANGE.0.ln(), SPEED_PLL_RANGE.1.ln());
            let grid = (0..SET_SCAN).map(|i| (lo + (hi - lo) * i as f64 / (SET_SCAN - 1) as f64).exp());
            let mut kept = vec![alpha];
            let n = (2 * counted.get()) as f64;
            for a in grid {
                if (loss(Some(a))? - with) * n / with < CHI2_1_95 {
                    kept.push(a);
                }
            }
            Some([kept.iter().copied().fold(alpha, f64::min), kept.iter().copied().fold(alpha, f64::max)])
        }
    };
    Ok(LoopSearch { input: at(chosen), note: Some(note), set })
}

/// After the final fit `fit` at the loop's bandwidth `alpha` with its set `set`, the same
/// fit repeated at the set's ends other than `alpha` (`refit(bandwidth)`): an untrusted
/// `loop_ambiguous` warning when a motor parameter (`motor`) moves by more than
/// [`LOOP_AMBIGUOUS_Z`] of its standard errors, else a note of the largest move.
///
/// # Errors
/// Those of `refit`.
pub(crate) fn ambiguity(
    fit: &FitResult,
    alpha: f64,
    set: [f64; 2],
    motor: &[&str],
    refit: &dyn Fn(f64) -> Result<FitResult>,
) -> Result<(Option<Warning>, String)> {
    let mut worst = (0.0, String::new(), alpha);
    for end in set.into_iter().filter(|e| (e / alpha).ln().abs() > 0.05) {
        let other = refit(end)?;
        for name in motor {
            let (Some(a), Some(b)) = (fit.parameter(name), other.parameter(name)) else { continue };
            let z = (b.value - a.value).abs() / a.std_error;
            if z > worst.0 || !z.is_finite() {
                worst = (z, (*name).to_string(), end);
            }
        }
    }
    let (z, name, end) = worst;
    let text = format!(
        "bandwidths of {:.0} … {:.0} rad/s predict the log alike (likelihood ratio, 95 %); the final fit at {end:.0} \
         rad/s moves {} by {z:.2} standard errors",
        set[0],
        set[1],
        if name.is_empty() { "no parameter" } else { &name },
    );
    if z > LOOP_AMBIGUOUS_Z || !z.is_finite() {
        let message = format!(
            "the controller's phase-locked loop is not pinned by the log: {text}, so the estimates depend on a \
             loop the data cannot tell; give --speed-pll RAD_S if the drive's is known (or a log with less current \
             noise)"
        );
        return Ok((Some(Warning::untrusted("loop_ambiguous", message)), text));
    }
    Ok((None, format!("the controller's loop: {text}")))
}
