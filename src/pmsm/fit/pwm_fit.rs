//! The stages of a fit through the switching-resolved PWM inverter: the continuation over
//! smooth leg states ([`super::pwm_start::continuation`]), the fit of the model asked for,
//! then its sign mask ([`super::pwm_mask`]) and the final fit without the masked samples.

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::{FitResult, Weighting};
use crate::model::GreyBoxModel;
use crate::pmsm::fit::hold::HoldFits;
use crate::pmsm::fit::search::{SPEED_PLL_RANGE, golden_search};
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::pwm::{PmsmPwm, PwmInverter};

/// The fits of a PWM model from `start` (parameters `names`, model order) at the voltage
/// `input`, in stages; `model` makes the model of an inverter and input as configured by
/// the options, `fit` fits one (inverter, input, start, names, weighting, parameters held at
/// their start); notes in order. Returns the fits and the input of the final ones (the
/// controller's loop bandwidth searched when `pwm.search_speed_pll`) and the inverter of the
/// final fits (its leg state chosen).
///
/// A width `i_w` estimated by the unmasked fit is held at its estimate in the masked one:
/// only the samples near a zero crossing tell it, and the mask weights those out. That fit
/// is then compared with the sign's on the same samples, and the lower loss kept (the
/// unmasked width also holds the current's noise).
///
/// # Errors
/// Those of the fits, of the loop's search and of [`super::pwm_mask::sign_mask`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn stages(
    experiments: &[Experiment],
    pwm: &PwmInverter,
    input: VoltageInput,
    start: &[f64],
    names: &[&str],
    weighting: &dyn Weighting,
    model: &dyn Fn(PwmInverter, VoltageInput) -> Result<PmsmPwm>,
    fit: &Fit<'_>,
    notes: &mut Vec<String>,
) -> Result<(HoldFits, VoltageInput, PwmInverter)> {
    // The loss is rough where a predicted current crosses zero at a switching instant: the
    // fits of a smooth leg state of decreasing width lead to it. Also from a given start: a
    // nested fit of a part of the log that started at the whole fit's estimate would stay in
    // its basin, and the parts' agreement would not test whether that basin is the minimum.
    let mut last: Option<(FitResult, PwmInverter)> = None;
    for (stage, stage_names) in super::pwm_start::continuation(experiments, pwm, names) {
        let s = super::pwm_start::carried(last.as_ref().map(|l| &l.0), &stage_names, start, names);
        let fitted = fit(stage, input, &s, &stage_names, weighting, &[])?;
        last = Some((fitted.best.1, stage));
    }
    let Some((prev, stage)) = &last else {
        return Ok((fit(*pwm, input, start, names, weighting, &[])?, input, *pwm));
    };
    let (theta, note) = super::pwm_start::from_continuation(prev, stage.i_w, names, pwm, start);
    notes.push(note);
    let unmasked = fit(*pwm, input, &theta, names, weighting, &[])?;
    let theta = super::pwm_start::carried(Some(&unmasked.best.1), names, &theta, names);
    // The controller's loop where the model is closest to the log: at the unmasked estimate.
    let input = if pwm.search_speed_pll {
        let (input, note) = search_speed_pll(experiments, input, &theta, weighting, &|i| model(*pwm, i))?;
        notes.extend(note);
        input
    } else {
        input
    };
    // The samples whose sign is a coin toss at that estimate, weighted out.
    let (mask, note) = super::pwm_mask::sign_mask(experiments, &model(*pwm, input)?, &theta, weighting)?;
    notes.push(note);
    let held: &[&str] = if pwm.estimate_i_w { &["i_w"] } else { &[] };
    let fits = fit(*pwm, input, &theta, names, &mask, held)?;
    if !pwm.estimate_i_w {
        return Ok((fits, input, *pwm));
    }
    // The width the unmasked fit finds holds the measured current's noise as well as the
    // legs' parasitic capacitances (a one-step prediction from a noisy current turns its
    // signs near zero as a wide leg state would), and the atan's slow tail then reaches the
    // kept samples: 0.05 A of noise gave i_w = 0.015 A and r_s 2.5 % low. The sign's fit on
    // the same samples decides, by the lower loss.
    let sign = PwmInverter { i_w: None, estimate_i_w: false, ..*pwm };
    let sign_names: Vec<&str> = names.iter().copied().filter(|n| *n != "i_w").collect();
    let sign_start = super::pwm_start::carried(Some(&fits.best.1), &sign_names, &theta, names);
    let sign_fits = fit(sign, input, &sign_start, &sign_names, &mask, &[])?;
    let (width, hard) = (fits.best.1.fit.loss, sign_fits.best.1.fit.loss);
    let i_w = fits.best.1.parameter("i_w").map_or(f64::NAN, |p| p.value);
    let keep_sign = hard <= width;
    notes.push(format!(
        "PWM leg state on the masked samples: the width i_w = {i_w:.3e} A of the unmasked fit held (loss \
         {width:.6e}) against the sign ({hard:.6e}): {}",
        if keep_sign { "the sign" } else { "the width" }
    ));
    Ok(if keep_sign { (sign_fits, input, sign) } else { (fits, input, *pwm) })
}

/// One PWM fit: (inverter, input, start, names, weighting, parameters held at their start).
pub(crate) type Fit<'a> =
    dyn Fn(PwmInverter, VoltageInput, &[f64], &[&str], &dyn Weighting, &[&str]) -> Result<HoldFits> + 'a;

/// The bandwidth of the controller's phase-locked loop ([`controller_frame`]) by the lowest
/// one-step loss of `model` at `theta` (weighted by `weighting`) over [`SPEED_PLL_RANGE`]
/// (a scan and a golden-section search on its logarithm), or the logged angle and speed if
/// those predict better; the input and a note (none for the terminal voltage, which has no
/// controller's frame).
///
/// # Errors
/// Those of the model's `prepare` and [`PmsmPwm::sign_margins`].
///
/// [`controller_frame`]: crate::pmsm::model::interval::controller_frame
fn search_speed_pll(
    experiments: &[Experiment],
    input: VoltageInput,
    theta: &[f64],
    weighting: &dyn Weighting,
    model: &dyn Fn(VoltageInput) -> Result<PmsmPwm>,
) -> Result<(VoltageInput, Option<String>)> {
    let VoltageInput::Reference { delay, advance, .. } = input else {
        return Ok((input, None));
    };
    let at = |speed_pll: Option<f64>| VoltageInput::Reference { delay, advance, speed_pll };
    let loss = |speed_pll: Option<f64>| -> Result<f64> {
        let m = model(at(speed_pll))?;
        let mut sum = 0.0;
        for e in experiments {
            let margins = m.sign_margins(theta, &m.prepare(e)?)?;
            sum += margins
                .iter()
                .enumerate()
                .map(|(k, s)| weighting.sample_weight(e, k) * s.residual.powi(2))
                .sum::<f64>();
        }
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
    Ok((at(chosen), Some(note)))
}
