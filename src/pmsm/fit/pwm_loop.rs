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
//! Under current noise the search compares one-step losses at a fixed estimate, which the
//! loop chosen before has already moved: the pair (loop, estimate) can settle where neither
//! search nor fit moves it but the compensated criterion is not at its minimum. So there
//! the final fit at the loop is compared with the same fit at the logged angle and speed,
//! each by its compensated criterion at its own estimate ([`logged_or_loop`]).
//!
//! [`controller_frame`]: crate::pmsm::model::interval::controller_frame

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::{CriterionCorrection, FitResult, Warning, Weighting};
use crate::model::GreyBoxModel;
use crate::pmsm::fit::search::{COARSE, SPEED_PLL_RANGE, brent_search, walk_search};
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::pwm::PmsmPwm;

/// Standard errors by which a motor parameter's estimates at the ends of the loop's set
/// may differ from the fit's before the fit is untrusted (`loop_ambiguous`).
pub const LOOP_AMBIGUOUS_Z: f64 = 3.0;

/// Log-spaced bandwidths of the scan that finds the set (the search's own scan then).
const SET_SCAN: usize = 25;

/// χ²₁(0.95): the likelihood-ratio bound of the set.
const CHI2_1_95: f64 = 3.841;

/// Akaike's penalty of one parameter in the likelihood ratio: the loop's bandwidth against
/// the logged frame ([`logged_or_loop`]).
const AIC_PENALTY: f64 = 2.0;

/// The loop's search: the chosen input, a note, and the set of bandwidths the
/// likelihood-ratio test does not reject (`[lo, hi]` \[rad/s\], `None` when the logged
/// frame predicts better, `[α, α]` when the set was not scanned).
pub(crate) struct LoopSearch {
    pub input: VoltageInput,
    pub note: Option<String>,
    pub set: Option<[f64; 2]>,
}

/// The one-step loss of a PWM model along the controller's loop bandwidth: `model` at
/// `theta`, the samples weighted by `weighting`.
struct LoopLoss<'a> {
    experiments: &'a [Experiment],
    theta: &'a [f64],
    weighting: &'a dyn Weighting,
    model: &'a dyn Fn(VoltageInput) -> Result<PmsmPwm>,
    delay: usize,
    advance: f64,
}

impl LoopLoss<'_> {
    /// The input at bandwidth `speed_pll` \[rad/s\] (`None`: the logged angle and speed).
    fn at(&self, speed_pll: Option<f64>) -> VoltageInput {
        VoltageInput::Reference { delay: self.delay, advance: self.advance, speed_pll }
    }

    /// Half the weighted sum of squared one-step residuals at `speed_pll`, and the
    /// residuals counted (weight above 0, not the first sample).
    fn loss(&self, speed_pll: Option<f64>) -> Result<(f64, usize)> {
        let m = (self.model)(self.at(speed_pll))?;
        let (mut sum, mut n) = (0.0, 0);
        for e in self.experiments {
            let residuals = m.one_step_residuals(self.theta, &m.prepare(e)?)?;
            for (k, r) in residuals.iter().enumerate() {
                let w = self.weighting.sample_weight(e, k);
                sum += w * r.powi(2);
                n += usize::from(w > 0.0 && k > 0);
            }
        }
        Ok((0.5 * sum, n))
    }

    /// The bandwidths whose loss `V` the likelihood-ratio test does not reject against the
    /// loss `with` at `alpha` over `counted` residuals, among the points `scan` (bandwidth
    /// \[rad/s\], loss) of the search's log-spaced scan of [`SET_SCAN`]:
    /// `[lo, hi]` \[rad/s\].
    fn set(alpha: f64, with: f64, counted: usize, scan: &[(f64, f64)]) -> [f64; 2] {
        let kept = scan.iter().filter(|(_, v)| Self::within(*v, with, counted)).map(|(a, _)| *a);
        kept.fold([alpha, alpha], |[lo, hi], a| [lo.min(a), hi.max(a)])
    }

    /// Whether the likelihood-ratio test keeps a loss `v` against the lowest `with` over
    /// `counted` residuals: `(V − V_min) n / V_min < χ²₁(0.95)`, `n` twice `counted` (two
    /// outputs). False for a `v` that is not a number.
    fn within(v: f64, with: f64, counted: usize) -> bool {
        (v - with) * (2 * counted) as f64 / with < CHI2_1_95
    }
}

/// How [`search_speed_pll`] scans the loop's bandwidths.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LoopScan {
    /// Whether the likelihood-ratio set is wanted: the scan of [`SET_SCAN`] points, else
    /// [`COARSE`]'s and the set the bandwidth found alone.
    pub set: bool,
    /// A bandwidth found before \[rad/s\] to walk the scan from ([`walk_search`]); `None`:
    /// the whole scan.
    pub near: Option<f64>,
}

/// The bandwidth of the controller's phase-locked loop by the lowest one-step loss of
/// `model` at `theta` (weighted by `weighting`) over [`SPEED_PLL_RANGE`] (a scan and
/// Brent's method on its logarithm, [`brent_search`]), or the logged angle and speed if those predict
/// better; and the bandwidths whose loss `V` the likelihood-ratio test does not reject,
/// `(V − V_min) n / V_min < χ²₁(0.95)` (`n` counted residuals; Ljung, *System
/// Identification*, 2nd ed., 16.4), over a log-spaced scan (none for the terminal voltage,
/// which has no controller's frame). Without `scan.set` (a nested fit, which runs no
/// checks, or the first search on the leading share of the logs, whose set is not used) the
/// set is the bandwidth found alone, and the scan is [`COARSE`]'s. With `scan.near` (a
/// bandwidth found before) the scan is walked from it until the loss rises outside the
/// likelihood-ratio bound each way ([`walk_search`]): the same bandwidth and set wherever
/// the loss has one basin along the scan, in fewer one-step passes (the second search, at
/// the final estimate, after the first has scanned the whole range; docs/performance.md).
///
/// # Errors
/// Those of the model's `prepare` and [`PmsmPwm::one_step_residuals`].
pub(crate) fn search_speed_pll(
    experiments: &[Experiment],
    input: VoltageInput,
    theta: &[f64],
    weighting: &dyn Weighting,
    model: &dyn Fn(VoltageInput) -> Result<PmsmPwm>,
    scan: LoopScan,
) -> Result<LoopSearch> {
    let VoltageInput::Reference { delay, advance, .. } = input else {
        return Ok(LoopSearch { input, note: None, set: None });
    };
    let loss = LoopLoss { experiments, theta, weighting, model, delay, advance };
    // The scan for the set is the search's own when the set is wanted.
    let points = if scan.set { SET_SCAN } else { COARSE };
    let (logged, counted) = loss.loss(None)?;
    let loss_at = |a| Ok(loss.loss(Some(a))?.0);
    let found = match scan.near {
        Some(near) => {
            let within = |v: f64, best: f64| LoopLoss::within(v, best, counted);
            walk_search(SPEED_PLL_RANGE, true, points, near, within, loss_at)?
        }
        None => brent_search(SPEED_PLL_RANGE, true, points, loss_at)?,
    };
    let (alpha, with) = (found.best, found.loss);
    let chosen = if with < logged { Some(alpha) } else { None };
    let note = format!(
        "the controller's frame: a phase-locked loop of {alpha:.1} rad/s on theta_m (one-step loss {with:.6e}) \
         against the logged angle and speed ({logged:.6e}): {}",
        if chosen.is_some() { "the loop" } else { "the logged" }
    );
    let set = match chosen {
        None => None,
        Some(alpha) if !scan.set => Some([alpha, alpha]),
        Some(alpha) => Some(LoopLoss::set(alpha, with, counted, &found.scan)),
    };
    Ok(LoopSearch { input: loss.at(chosen), note: Some(note), set })
}

/// The relative change of bandwidth (in its logarithm) beyond which a search moves the loop.
pub(crate) const MOVED: f64 = 0.05;

/// Whether the search `again` at the final estimate moves the loop of `kept` (the input the
/// final fit was made at): to another kind of frame, by more than [`MOVED`], or out of
/// the likelihood-ratio set `again` reports (the bandwidth kept is then one that the final
/// estimate's loss rejects: on the independent 3 kHz IPM log the first search's 2058 rad/s
/// against a set of 2053 … 2053 at the final estimate, the drive's observer at 2053.3
/// (motulator's sensored observer pole, 2π·400 rad/s matched to the sampling period), and
/// `l_q` 5 of its noise-free standard errors apart between the two).
pub(crate) fn moved(again: &LoopSearch, kept: VoltageInput) -> bool {
    match (again.input, kept) {
        (
            VoltageInput::Reference { speed_pll: Some(a), .. },
            VoltageInput::Reference { speed_pll: Some(b), .. },
        ) => (a / b).ln().abs() > MOVED || again.set.is_some_and(|[lo, hi]| b < lo || b > hi),
        (a, b) => a != b,
    }
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

/// Under current noise (the final fits' weighting compensated by `correction`): the final
/// fit `at_loop` at the loop's bandwidth `alpha` \[rad/s\] against the same fit at the logged
/// angle and speed, `at_logged`, each by its compensated criterion `J` at its own estimate
/// on the same samples (module docs). The loop is kept where it lowers `J` by more than
/// Akaike's penalty of its one parameter, `2 (J_logged − J_loop) / σ² > 2` (σ² = 2V / n
/// of the loop's fit over the n residuals its criterion counts, the mean squared residual
/// with the default weights; a ratio that is not a number takes the logged frame;
/// Akaike's information criterion, Ljung, *System Identification*, 2nd ed., 16.4): the
/// logged frame is the loop's limit at an infinite bandwidth. Both `J` take the same
/// correction, made in the first search's frame: with hard leg states its `c(θ)` does not
/// depend on the frame (the transition `e^{Ah}` is the motor's), with smooth ones only
/// through the pieces' currents. Returns whether the logged frame is taken, and a note.
///
/// On the drive simulator's 4 kHz log (the drive advances with the logged speed; 0.05 A
/// per phase, seeds 1–4, hard and soft legs) that ratio was −0.5 … −10.4, and the pair had
/// settled at 758–980 rad/s with `l_s` 1.1–3.1 % low (z down to −3.75); on the three shared
/// motulator logs (an observer of 2224 rad/s), seeds 1–2 with the same noise, 3.4 … 19.0.
///
/// # Errors
/// Those of the correction's value.
pub(crate) fn logged_or_loop(
    at_loop: &FitResult,
    at_logged: &FitResult,
    alpha: f64,
    model: &PmsmPwm,
    correction: &dyn CriterionCorrection,
    experiments: usize,
) -> Result<(bool, String)> {
    let j_loop = super::pwm_noise::compensated_loss(at_loop, model, correction, experiments)?;
    let j_logged = super::pwm_noise::compensated_loss(at_logged, model, correction, experiments)?;
    // σ² of the criterion's own metric: 2V over the residuals it counts (the mean squared
    // residual with the default weights).
    let stats = &at_loop.fit;
    let counted = (stats.counted.unwrap_or(stats.samples) * stats.outputs.len().max(1)) as f64;
    let ratio = (j_logged - j_loop) * counted / stats.loss;
    let logged = ratio.is_nan() || ratio <= AIC_PENALTY;
    let note = format!(
        "the controller's frame under current noise, each fit by its compensated criterion at its own estimate: \
         the loop of {alpha:.1} rad/s {j_loop:.6e}, the logged angle and speed {j_logged:.6e} (likelihood ratio \
         {ratio:.2}; the loop is kept where it exceeds Akaike's penalty {AIC_PENALTY}): {}",
        if logged { "the logged" } else { "the loop" }
    );
    Ok((logged, note))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(alpha: Option<f64>) -> VoltageInput {
        VoltageInput::Reference { delay: 1, advance: 1.5, speed_pll: alpha }
    }

    fn search(alpha: Option<f64>, set: Option<[f64; 2]>) -> LoopSearch {
        LoopSearch { input: at(alpha), note: None, set }
    }

    /// A bandwidth kept outside the set the final estimate's search reports is moved, as is
    /// one more than 5 % away or another frame; one inside the set within 5 % is kept.
    #[test]
    fn a_loop_outside_the_final_set_is_moved() {
        assert!(moved(&search(Some(2053.0), Some([2053.0, 2053.4])), at(Some(2058.1))));
        assert!(!moved(&search(Some(2053.0), Some([2050.0, 2058.5])), at(Some(2058.1))));
        assert!(!moved(&search(Some(2053.0), None), at(Some(2058.1))));
        assert!(moved(&search(Some(2300.0), None), at(Some(2058.1))));
        assert!(moved(&search(None, None), at(Some(2058.1))));
        assert!(!moved(&search(None, None), at(None)));
    }
}
