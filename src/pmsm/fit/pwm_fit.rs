//! The stages of a fit through the switching-resolved PWM inverter: the continuation over
//! smooth leg states ([`super::pwm_start::continuation`]), the fit of the model asked for,
//! then its sign mask ([`super::pwm_mask`]) and the final fit without the masked samples.

use super::pwm_leg_state::{Final, Fit, OwnMask, Sides, on_own_mask};
use crate::error::Result;
use crate::estimate::{FitResult, Warning, Weighting};
use crate::pmsm::fit::hold::HoldFits;
use crate::pmsm::log::DqLogs;
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
/// Under current noise (the final criterion compensated) a loop found is compared with
/// the logged angle and speed, each by the compensated criterion of its own final fit on
/// the same samples ([`super::pwm_loop::logged_or_loop`]): the input returned may then be
/// the logged frame although the loop was searched. A width given (no continuation) runs
/// through the same stages from `start`.
///
/// # Errors
/// Those of the fits, of the loop's search, of [`super::pwm_mask::sign_mask`] and of the
/// criterion's correction.
#[allow(clippy::too_many_arguments)]
pub(crate) fn stages(
    checked: bool,
    dq: &DqLogs<'_>,
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
    let experiments = dq.experiments();
    let mut last: Option<(FitResult, PwmInverter)> = None;
    for (stage, stage_names) in super::pwm_start::continuation(dq.views(), pwm, names) {
        let s = super::pwm_start::carried(last.as_ref().map(|l| &l.0), &stage_names, start, names);
        let fitted = stage_fit(stage, input, &s, &stage_names, weighting, &[])?;
        last = Some((fitted.best.1, stage));
    }
    // A width given (no continuation) goes through the same stages from the start: the
    // loop, the mask and, under current noise, the compensation through its smooth legs'
    // transition (before, its fit ran unmasked and uncompensated: L 7.8 % low on a 4 kHz
    // log with 0.05 A per phase, its parts disagreeing).
    let theta = match &last {
        Some((prev, stage)) => {
            let (theta, note) = super::pwm_start::from_continuation(prev, stage.i_w, names, pwm, start);
            notes.push(note);
            theta
        }
        None => start.to_vec(),
    };
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
    let sides = Sides { experiments, pwm, input, weighting, model, fit, stage_fit };
    let mut last = if pwm.estimate_i_w {
        // At the width held, the masked fit is a start (of the sign's fit) and a loss to
        // compare with the sign's: at the stages' tolerance, converged only if it is kept.
        let fits = stage_fit(*pwm, input, &theta, &names, &mask, &["i_w"])?;
        super::pwm_leg_state::leg_state(&sides, fits, &names, &theta, &mask, notes)?
    } else {
        let fits = fit(*pwm, input, &theta, &names, &mask, &[])?;
        match super::pwm_leg_state::compensate(&sides, *pwm, &fits, &names, &theta, &mask, notes)? {
            Some((fits, compensated)) => {
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
    if last.own_mask.is_none()
        && let Some(OwnMask { mask: again, fits, start, note }) =
            on_own_mask(&sides, last.inverter, &last.fits, &last.names, &last.start, &mask, held)?
    {
        notes.push(format!("at the final estimate, {note}: refitted"));
        last.fits = fits;
        last.start = start;
        last.own_mask = Some(again);
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
    // Under current noise, the loop against the logged frame by the compensated criterion
    // of each one's own fit (`pwm_loop::logged_or_loop`).
    if let (Some(correction), VoltageInput::Reference { delay, advance, speed_pll: Some(alpha) }) =
        (final_weighting.criterion_correction(), input)
    {
        let logged = VoltageInput::Reference { delay, advance, speed_pll: None };
        let start = super::pwm_start::carried(Some(&last.fits.best.1), &last.names, &last.start, &last.names);
        let other = fit(last.inverter, logged, &start, &last.names, final_weighting, held)?;
        let (take, note) = super::pwm_loop::logged_or_loop(
            &last.fits.best.1,
            &other.best.1,
            alpha,
            &model(last.inverter, input)?,
            correction,
            experiments.len(),
        )?;
        notes.push(note);
        if take {
            return Ok((other, logged, last.inverter));
        }
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
