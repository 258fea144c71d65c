//! The stages of a fit through the switching-resolved PWM inverter: the continuation over
//! smooth leg states ([`super::pwm_start::continuation`]), the fit of the model asked for,
//! then its sign mask ([`super::pwm_mask`]) and the final fit without the masked samples.

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::{FitResult, Warning, Weighting};
use crate::pmsm::fit::hold::HoldFits;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::pwm::{PmsmPwm, PwmInverter};

/// The fits of a PWM model from `start` (parameters `names`, model order) at the voltage
/// `input`, in stages; `model` makes the model of an inverter and input as configured by
/// the options, `fit` fits one (inverter, input, start, names, weighting, parameters held at
/// their start), `stage_fit` the same at [`crate::pmsm::options::stage_options`]'
/// tolerances for the fits that lead to the final one (the continuation's, the unmasked
/// fit and the masked fit at an estimated width); notes and warnings in order.
/// Returns the fits and the input of the final ones (the controller's loop bandwidth
/// searched when `pwm.search_speed_pll`) and the inverter of the final fits (its leg state
/// chosen).
///
/// A width `i_w` estimated by the unmasked fit is held at its estimate in the masked one:
/// only the samples near a zero crossing tell it, and the mask weights those out. That fit
/// is then compared with the sign's on the same samples, and the lower loss kept (the
/// unmasked width also holds the current's noise).
///
/// With `checked` false (a nested fit without setup checks) the loop's likelihood-ratio set
/// is not scanned and the fit not repeated at its ends (`loop_ambiguous` is a check): the
/// same final fit, without the ~25 one-step passes of each scan.
///
/// # Errors
/// Those of the fits, of the loop's search and of [`super::pwm_mask::sign_mask`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn stages(
    checked: bool,
    experiments: &[Experiment],
    pwm: &PwmInverter,
    input: VoltageInput,
    start: &[f64],
    names: &[&str],
    weighting: &dyn Weighting,
    model: &dyn Fn(PwmInverter, VoltageInput) -> Result<PmsmPwm>,
    fit: &Fit<'_>,
    stage_fit: &Fit<'_>,
    notes: &mut Vec<String>,
    warnings: &mut Vec<Warning>,
) -> Result<(HoldFits, VoltageInput, PwmInverter)> {
    // The loss is rough where a predicted current crosses zero at a switching instant: the
    // fits of a smooth leg state of decreasing width lead to it. Also from a given start: a
    // nested fit of a part of the log that started at the whole fit's estimate would stay in
    // its basin, and the parts' agreement would not test whether that basin is the minimum.
    let mut last: Option<(FitResult, PwmInverter)> = None;
    for (stage, stage_names) in super::pwm_start::continuation(experiments, pwm, names) {
        let s = super::pwm_start::carried(last.as_ref().map(|l| &l.0), &stage_names, start, names);
        let fitted = stage_fit(stage, input, &s, &stage_names, weighting, &[])?;
        last = Some((fitted.best.1, stage));
    }
    let Some((prev, stage)) = &last else {
        return Ok((fit(*pwm, input, start, names, weighting, &[])?, input, *pwm));
    };
    let (theta, note) = super::pwm_start::from_continuation(prev, stage.i_w, names, pwm, start);
    notes.push(note);
    let unmasked = stage_fit(*pwm, input, &theta, names, weighting, &[])?;
    let theta = super::pwm_start::carried(Some(&unmasked.best.1), names, &theta, names);
    // The controller's loop where the model is closest to the log: at the unmasked estimate,
    // on the samples whose signs are no coin toss there. On all samples the loss along the
    // loop's bandwidth is dominated by the sign flips a noisy current turns (each a spike of
    // `U_dc t_d / L`): with 0.05 A of noise per phase on the shared 3 µs log the search then
    // scattered over 1560 … 3270 rad/s around the drive's 2224, and the estimates with it.
    let (input, set) = if pwm.search_speed_pll {
        let (coin_tosses, _) =
            super::pwm_mask::sign_mask(experiments, &model(*pwm, input)?, &theta, weighting)?;
        let found = super::pwm_loop::search_speed_pll(
            experiments,
            input,
            &theta,
            &coin_tosses,
            &|i| model(*pwm, i),
            checked,
        )?;
        notes.extend(found.note);
        (found.input, found.set)
    } else {
        (input, None)
    };
    // The samples whose sign is a coin toss at that estimate, weighted out.
    let (mask, note) = super::pwm_mask::sign_mask(experiments, &model(*pwm, input)?, &theta, weighting)?;
    notes.push(note);
    let names = names.to_vec();
    let mut last = if pwm.estimate_i_w {
        // At the width held, the masked fit is a start (of the sign's fit) and a loss to
        // compare with the sign's: at the stages' tolerance, converged only if it is kept.
        let fits = stage_fit(*pwm, input, &theta, &names, &mask, &["i_w"])?;
        leg_state(experiments, fits, pwm, input, &names, &theta, &mask, model, fit, notes, warnings)?
    } else {
        let fits = fit(*pwm, input, &theta, &names, &mask, &[])?;
        match compensate(experiments, &fits, *pwm, input, &names, &theta, &mask, model, fit, notes)? {
            Some((fits, compensated, _)) => {
                Final { fits, inverter: *pwm, names, start: theta, own_mask: Some(compensated) }
            }
            None => Final { fits, inverter: *pwm, names, start: theta, own_mask: None },
        }
    };
    let held: &[&str] = if last.inverter.estimate_i_w { &["i_w"] } else { &[] };
    // The mask again at the final estimate, and the final fit on it where it weights out
    // other samples: a period whose predicted current crosses zero at a switching instant
    // near the final estimate but not near the unmasked one (which stopped at the stages'
    // tolerance) keeps a kink in the loss there: without this the shared IPM log's final
    // fit stopped at one in each variant tried, a Gauss-Newton step of 0.27-2.3 standard
    // errors still to go (`not_stationary`).
    if last.own_mask.is_none() {
        let start = super::pwm_start::carried(Some(&last.fits.best.1), &last.names, &last.start, &last.names);
        let (again, note) =
            super::pwm_mask::sign_mask(experiments, &model(last.inverter, input)?, &start, weighting)?;
        if !again.same_samples(&mask) {
            notes.push(format!("at the final estimate, {note}: refitted"));
            last.fits = fit(last.inverter, input, &start, &last.names, &again, held)?;
            last.start = start;
            last.own_mask = Some(again);
        }
    }
    let Some(mut set) = set else { return Ok((last.fits, input, last.inverter)) };
    let final_weighting: &dyn Weighting = match &last.own_mask {
        Some(m) => m,
        None => &mask,
    };
    let start = super::pwm_start::carried(Some(&last.fits.best.1), &last.names, &last.start, &last.names);
    // The loop again at the final estimate: at the unmasked one the search's bandwidth also
    // made up for that estimate's bias (0.05 A per phase: 6700 rad/s for the drive's 2224).
    // Its likelihood-ratio set is scanned only if it moves (the first search's set holds
    // otherwise).
    let again = super::pwm_loop::search_speed_pll(
        experiments,
        input,
        &start,
        final_weighting,
        &|i| model(last.inverter, i),
        false,
    )?;
    let moved = match (again.input, input) {
        (
            VoltageInput::Reference { speed_pll: Some(a), .. },
            VoltageInput::Reference { speed_pll: Some(b), .. },
        ) => (a / b).ln().abs() > 0.05,
        (a, b) => a != b,
    };
    let mut input = input;
    if moved {
        notes.extend(again.note.map(|n| format!("at the final estimate, {n}: refitted there")));
        last.fits = fit(last.inverter, again.input, &start, &last.names, final_weighting, held)?;
        input = again.input;
        // The set of the search that moved (scanned only now: unused when it does not).
        let scanned = match (checked, again.set) {
            (true, Some(_)) => {
                super::pwm_loop::scanned_set(experiments, input, &start, final_weighting, &|i| {
                    model(last.inverter, i)
                })?
            }
            (_, found) => found,
        };
        set = match scanned {
            Some(s) => s,
            None => return Ok((last.fits, input, last.inverter)),
        };
    }
    if let (true, VoltageInput::Reference { delay, advance, speed_pll: Some(alpha) }) = (checked, input) {
        let inverter_names = last.inverter.parameter_names();
        let motor: Vec<&str> = last.names.iter().copied().filter(|n| !inverter_names.contains(n)).collect();
        let start = super::pwm_start::carried(Some(&last.fits.best.1), &last.names, &last.start, &last.names);
        let refit = |a: f64| {
            let at = VoltageInput::Reference { delay, advance, speed_pll: Some(a) };
            fit(last.inverter, at, &start, &last.names, final_weighting, held).map(|f| f.best.1)
        };
        let (warning, note) = super::pwm_loop::ambiguity(&last.fits.best.1, alpha, set, &motor, &refit)?;
        notes.push(note);
        warnings.extend(warning);
    }
    Ok((last.fits, input, last.inverter))
}

/// The final fit of [`stages`]: its fits, inverter, free parameters and start, and its mask
/// when that is not the stages' (compensated for the current's noise, or taken again at
/// the final estimate).
struct Final<'w, 'n> {
    fits: HoldFits,
    inverter: PwmInverter,
    names: Vec<&'n str>,
    start: Vec<f64>,
    own_mask: Option<super::pwm_mask::SignMask<'w>>,
}

/// The leg state of a fit whose width `i_w` the unmasked fit estimated (`fits`, the masked
/// fit at that width held at the stages' tolerance, converged here if the width is kept;
/// parameters `names` from `theta`): the width kept or the sign
/// taken, by the lower loss on the masked samples, or the sign where the measured current's
/// noise is material (the width holds it) with its criterion compensated; then a width
/// wider than that noise makes of a hard switch ([`NOISE_WIDTH`]) is an untrusted
/// `leg_state_unresolved` warning in `warnings`.
///
/// # Errors
/// Those of the fits and of [`compensate`].
#[allow(clippy::too_many_arguments)]
fn leg_state<'w, 'n>(
    experiments: &[Experiment],
    fits: HoldFits,
    pwm: &PwmInverter,
    input: VoltageInput,
    names: &[&'n str],
    theta: &[f64],
    mask: &super::pwm_mask::SignMask<'w>,
    model: &dyn Fn(PwmInverter, VoltageInput) -> Result<PmsmPwm>,
    fit: &Fit<'_>,
    notes: &mut Vec<String>,
    warnings: &mut Vec<Warning>,
) -> Result<Final<'w, 'n>> {
    // The width the unmasked fit finds holds the measured current's noise as well as the
    // legs' parasitic capacitances (a one-step prediction from a noisy current turns its
    // signs near zero as a wide leg state would), and the atan's slow tail then reaches the
    // kept samples: 0.05 A of noise gave i_w = 0.015 A and r_s 2.5 % low. Where that noise
    // is material the sign is taken (and its criterion compensated); otherwise the sign's
    // fit on the same samples decides, by the lower loss.
    let sign = PwmInverter { i_w: None, estimate_i_w: false, ..*pwm };
    let sign_names: Vec<&'n str> = names.iter().copied().filter(|n| *n != "i_w").collect();
    let sign_start = super::pwm_start::carried(Some(&fits.best.1), &sign_names, theta, names);
    let sign_fits = fit(sign, input, &sign_start, &sign_names, mask, &[])?;
    let (width, hard) = (fits.best.1.fit.loss, sign_fits.best.1.fit.loss);
    let i_w = fits.best.1.parameter("i_w").map_or(f64::NAN, |p| p.value);
    let compensated =
        compensate(experiments, &sign_fits, sign, input, &sign_names, &sign_start, mask, model, fit, notes)?;
    let keep_sign = compensated.is_some() || hard <= width;
    // A width the noise cannot make: the legs switch softly, which the sign taken under
    // this noise does not describe.
    if let Some(rms) = compensated.as_ref().map(|c| c.2).filter(|rms| i_w > NOISE_WIDTH * rms) {
        warnings.push(Warning::untrusted(
            "leg_state_unresolved",
            format!(
                "the unmasked fit's PWM leg-state width i_w = {i_w:.3e} A is wider than the measured current's noise \
                 makes of a hard switch ({:.3e} A, σ = {rms:.3e} A per axis), so the inverter's legs switch softly \
                 (parasitic capacitances); under this noise the fit takes the sign, which does not describe them, \
                 and its estimates carry that model error; fit a log with less current noise (a width given with \
                 --leg-state-width is fitted without the noise's compensation: on a generated log with 0.05 A per \
                 phase that fit's parts disagreed, L 8 % low)",
                NOISE_WIDTH * rms
            ),
        ));
    }
    notes.push(format!(
        "PWM leg state on the masked samples: the width i_w = {i_w:.3e} A of the unmasked fit held (loss \
         {width:.6e}) against the sign ({hard:.6e}): {}",
        match (keep_sign, compensated.is_some()) {
            (true, true) => "the sign (the measured current's noise is material, and the width holds it)",
            (true, false) => "the sign",
            (false, _) => "the width",
        }
    ));
    Ok(match (keep_sign, compensated) {
        (true, Some((fits, m, _))) => {
            Final { fits, inverter: sign, names: sign_names, start: sign_start, own_mask: Some(m) }
        }
        (true, None) => {
            Final { fits: sign_fits, inverter: sign, names: sign_names, start: sign_start, own_mask: None }
        }
        (false, _) => {
            // Converged from the stages' tolerance.
            let start = super::pwm_start::carried(Some(&fits.best.1), names, theta, names);
            let fits = fit(*pwm, input, &start, names, mask, &["i_w"])?;
            Final { fits, inverter: *pwm, names: names.to_vec(), start, own_mask: None }
        }
    })
}

/// The final fit `fits` (parameters `names`, from `start`) of a PWM model whose leg states
/// are hard signs and whose predictor restarts from the measured current, refitted from its
/// estimate with the criterion compensated for the measured current's noise on that start
/// where it is material ([`super::pwm_noise`]), with the compensated mask; `None`
/// otherwise (other leg states or gains, or noise below
/// [`super::pwm_noise::START_NOISE_SHARE`]); and the noise's rms per axis \[A\].
///
/// # Errors
/// Those of [`super::pwm_noise::compensation`] and of the fit.
#[allow(clippy::too_many_arguments)]
fn compensate<'w>(
    experiments: &[Experiment],
    fits: &HoldFits,
    inverter: PwmInverter,
    input: VoltageInput,
    names: &[&str],
    start: &[f64],
    mask: &super::pwm_mask::SignMask<'w>,
    model: &dyn Fn(PwmInverter, VoltageInput) -> Result<PmsmPwm>,
    fit: &Fit<'_>,
    notes: &mut Vec<String>,
) -> Result<Option<(HoldFits, super::pwm_mask::SignMask<'w>, f64)>> {
    let hard = inverter.i_w.is_none_or(|w| w <= 0.0) && !inverter.estimate_i_w;
    if !hard || inverter.predictor_gain != Some(1.0) {
        return Ok(None);
    }
    let super::pwm_noise::StartCompensation { correction, note, rms } =
        super::pwm_noise::compensation(experiments, &model(inverter, input)?, &fits.best.1, mask)?;
    notes.push(note);
    let Some(correction) = correction else { return Ok(None) };
    let start = super::pwm_start::carried(Some(&fits.best.1), names, start, names);
    let compensated = mask.compensated(correction);
    Ok(Some((fit(inverter, input, &start, names, &compensated, &[])?, compensated, rms)))
}

/// The widest smooth leg state the measured current's noise makes of a hard switch, per
/// unit of its rms per axis σ: the expected sign of a current under Gaussian noise,
/// `erf(i / (√2 σ))`, has the slope `√(2/π) / σ` at zero, which `(2/π) atan(i / i_w)` has
/// at `i_w = σ √(2/π)`. On five logs whose inverter switches hard, with 0.05 A of noise per
/// phase (σ 0.041 A), the unmasked fit's width was 0.013–0.017 A (0.3–0.4 σ) in every seed;
/// on one whose legs switch softly over 0.05 A it was 0.052–0.056 A (1.3–1.4 σ).
pub(crate) const NOISE_WIDTH: f64 = 0.797_884_560_802_865_4;

/// One PWM fit: (inverter, input, start, names, weighting, parameters held at their start).
pub(crate) type Fit<'a> =
    dyn Fn(PwmInverter, VoltageInput, &[f64], &[&str], &dyn Weighting, &[&str]) -> Result<HoldFits> + 'a;
