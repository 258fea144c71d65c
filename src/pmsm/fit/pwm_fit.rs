//! The stages of a fit through the switching-resolved PWM inverter: the continuation over
//! smooth leg states ([`super::pwm_start::continuation`]), the fit of the model asked for,
//! then its sign mask ([`super::pwm_mask`]) and the final fit without the masked samples.

use super::pwm_leg_state::{Final, Fit, OwnMask, Sides, on_own_mask};
use super::pwm_loop::LoopScan;
use crate::error::{Error, Result};
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
/// The continuation and the loop's first search take a share of each log's periods
/// ([`super::pwm_start::leading_logs`]): they lead into the loss's basin; the unmasked fit
/// (whose width decides the leg state) starts there too and ends on every sample; the mask,
/// the masked fits and the loop's second search, whose likelihood-ratio set is the one
/// reported, take every sample.
///
/// A width `i_w` estimated by the unmasked fit is held at its estimate in the masked one:
/// only the samples near a zero crossing tell it, and the mask weights those out. That fit
/// is then compared with the sign's on the same samples, and the lower loss kept (the
/// unmasked width also holds the current's noise).
///
/// With `checked` false (a nested fit without setup checks) the loop's likelihood-ratio set
/// is not scanned and the fit not repeated at its ends (`loop_ambiguous` is a check): the
/// same final fit, without the scan's extra one-step passes.
///
/// Under current noise (the final criterion compensated) a loop found is compared with
/// the logged angle and speed, each by the compensated criterion of its own final fit on
/// the same samples ([`super::pwm_loop::logged_or_loop`]): the input returned may then be
/// the logged frame although the loop was searched. A width given (no continuation) runs
/// through the same stages from `start`. The second search moves the loop where the
/// bandwidth kept lies outside the set it reports ([`super::pwm_loop::moved`]). A final
/// fit that stops short of a minimum without the criterion's compensation is refitted on
/// a wider sign mask ([`Kinks::unkinked`]).
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
    // The continuation and the loop's first search take a share of each log's periods
    // ([`super::pwm_start::leading_logs`]); the unmasked fit, the mask and the masked fits
    // take them all.
    // Made only where a stage takes it (a width given and the loop not searched: none).
    let continuation = super::pwm_start::continuation(dq.views(), pwm, names);
    let leading = if continuation.is_empty() && !pwm.search_speed_pll {
        None
    } else {
        super::pwm_start::leading_logs(experiments)?
    };
    let lead = leading.as_deref().unwrap_or(experiments);
    let mut last: Option<(FitResult, PwmInverter)> = None;
    for (stage, stage_names) in continuation {
        let s = super::pwm_start::carried(last.as_ref().map(|l| &l.0), &stage_names, start, names);
        let fitted = stage_fit(lead, stage, input, &s, &stage_names, weighting, &[])?;
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
    // The unmasked fit first on the leading share, then on every sample from there: on the
    // whole logs its loss is rough where a predicted current crosses zero at a switching
    // instant, and from the continuation it walked along a valley in `l_s`, `t_d`, `u_th`
    // one short step at a time (the shared low-drop log: 19 trial steps, 3.2 s of a 10 s
    // fit); from the share's estimate it takes 1 to 4.
    let theta = match (&leading, &last) {
        (Some(lead), Some(_)) => {
            let first = stage_fit(lead, *pwm, input, &theta, names, weighting, &[])?;
            super::pwm_start::carried(Some(&first.best.1), names, &theta, names)
        }
        _ => theta,
    };
    let unmasked = stage_fit(experiments, *pwm, input, &theta, names, weighting, &[])?;
    let theta = super::pwm_start::carried(Some(&unmasked.best.1), names, &theta, names);
    // The controller's loop where the model is closest to the log: at the unmasked estimate,
    // on the samples whose signs are no coin toss there. On all samples the loss along the
    // loop's bandwidth is dominated by the sign flips a noisy current turns (each a spike of
    // `U_dc t_d / L`): with 0.05 A of noise per phase on the shared 3 µs log the search then
    // scattered over 1560 … 3270 rad/s around the drive's 2224, and the estimates with it.
    // Whether a loop was found (not the logged frame).
    let (input, looped) = if pwm.search_speed_pll {
        let at = model(*pwm, input)?;
        // A piece of the share may hold no sample the coin tosses leave (a wrong delay's
        // residuals make the margin wide): then the search takes every sample.
        let (logs, coin_tosses) = match super::pwm_mask::sign_mask(lead, &at, &theta, weighting) {
            Err(Error::TooShort { .. }) if leading.is_some() => {
                (experiments, super::pwm_mask::sign_mask(experiments, &at, &theta, weighting)?.0)
            }
            other => (lead, other?.0),
        };
        let scan = LoopScan { set: false, near: None };
        let found =
            super::pwm_loop::search_speed_pll(logs, input, &theta, &coin_tosses, &|i| model(*pwm, i), scan)?;
        notes.extend(found.note);
        (found.input, found.set.is_some())
    } else {
        (input, false)
    };
    // The samples whose sign is a coin toss at that estimate, weighted out.
    let (mask, note) = super::pwm_mask::sign_mask(experiments, &model(*pwm, input)?, &theta, weighting)?;
    notes.push(note);
    let names = names.to_vec();
    let sides = Sides { experiments, pwm, input, weighting, model, fit, stage_fit };
    let mut last = if pwm.estimate_i_w {
        // At the width held, the masked fit is a start (of the sign's fit) and a loss to
        // compare with the sign's: at the stages' tolerance, converged only if it is kept;
        // not made for a width negligible against the mask's margin (taken for the sign).
        super::pwm_leg_state::leg_state(&sides, &names, &theta, &mask, notes)?
    } else {
        let fits = fit(experiments, *pwm, input, &theta, &names, &mask, &[])?;
        match super::pwm_leg_state::compensate(&sides, *pwm, &fits, &names, &theta, &mask, notes)? {
            Some((fits, compensated)) => {
                Final { fits, inverter: *pwm, names, start: theta, own_mask: Some(compensated) }
            }
            None => Final { fits, inverter: *pwm, names, start: theta, own_mask: None },
        }
    };
    let held: &[&str] = if last.inverter.estimate_i_w { &["i_w"] } else { &[] };
    // The mask again at the final estimate, and the final fit on it where it weights out
    // other samples ([`own_mask_refit`]).
    let kinks = Kinks { experiments, weighting, model, fit, held };
    if !looped {
        own_mask_refit(&sides, &mut last, &mask, held, notes)?;
        return kinks.finish(last, input, &mask, notes);
    }
    let start = super::pwm_start::carried(Some(&last.fits.best.1), &last.names, &last.start, &last.names);
    // The loop again at the final estimate on every sample: at the unmasked one (on the
    // leading share) the search's bandwidth also made up for that estimate's bias (0.05 A
    // per phase: 6700 rad/s for the drive's 2224). Its likelihood-ratio set is scanned here,
    // at the final estimate, walked from the first search's bandwidth (which scanned the
    // whole range). Searched before the mask is taken again at that estimate, so that one
    // refit takes both the loop moved and that mask (on a noise-free log each moves the
    // fit, and each refit is a whole fit's time).
    let near = match input {
        VoltageInput::Reference { speed_pll, .. } => speed_pll,
        _ => None,
    };
    let again = super::pwm_loop::search_speed_pll(
        experiments,
        input,
        &start,
        last.own_mask.as_ref().unwrap_or(&mask),
        &|i| model(last.inverter, i),
        LoopScan { set: checked, near },
    )?;
    let moved = super::pwm_loop::moved(&again, input);
    let input = if moved { again.input } else { input };
    let refitted = own_mask_refit(&Sides { input, ..sides }, &mut last, &mask, held, notes)?;
    let final_weighting: &dyn Weighting = last.own_mask.as_ref().unwrap_or(&mask);
    if moved {
        notes.extend(again.note.map(|n| format!("at the final estimate, {n}: refitted there")));
        if !refitted {
            last.fits = fit(experiments, last.inverter, input, &start, &last.names, final_weighting, held)?;
        }
    }
    let Some([lo, hi]) = again.set else {
        return kinks.finish(last, input, &mask, notes);
    };
    // The loop kept lies in this set: a bandwidth outside it is moved
    // (`pwm_loop::moved`), and the set holds the search's own.
    let set = [lo, hi];
    // Under current noise, the loop against the logged frame by the compensated criterion
    // of each one's own fit (`pwm_loop::logged_or_loop`).
    if let (Some(correction), VoltageInput::Reference { delay, advance, speed_pll: Some(alpha) }) =
        (final_weighting.criterion_correction(), input)
    {
        let logged = VoltageInput::Reference { delay, advance, speed_pll: None };
        let start = super::pwm_start::carried(Some(&last.fits.best.1), &last.names, &last.start, &last.names);
        let other = fit(experiments, last.inverter, logged, &start, &last.names, final_weighting, held)?;
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
            fit(experiments, last.inverter, at, &start, &last.names, final_weighting, held).map(|f| f.best.1)
        };
        let (warning, note) = super::pwm_loop::ambiguity(&last.fits.best.1, alpha, set, &motor, &refit)?;
        notes.push(note);
        warnings.extend(warning);
    }
    kinks.finish(last, input, &mask, notes)
}

/// The final fits `last` refitted on the sign mask taken at their own estimate where that
/// weights out other samples than the stages' `mask` (at `sides`' input; `held` held at
/// their start), unless they have their own mask already: a period whose predicted
/// current crosses zero at a switching instant near the final estimate but not near the
/// unmasked one (which stopped at the stages' tolerance) keeps a kink in the loss there:
/// without this the shared IPM log's final fit stopped at one in each variant tried, a
/// Gauss-Newton step of 0.27-2.3 standard errors still to go (`not_stationary`). Whether
/// they were refitted.
///
/// # Errors
/// Those of [`on_own_mask`].
fn own_mask_refit<'w>(
    sides: &Sides<'_, 'w>,
    last: &mut Final<'w, '_>,
    mask: &super::pwm_mask::SignMask<'w>,
    held: &[&str],
    notes: &mut Vec<String>,
) -> Result<bool> {
    if last.own_mask.is_some() {
        return Ok(false);
    }
    let Some(OwnMask { mask: again, fits, start, note }) =
        on_own_mask(sides, last.inverter, &last.fits, &last.names, &last.start, mask, held)?
    else {
        return Ok(false);
    };
    notes.push(format!("at the final estimate, {note}: refitted"));
    last.fits = fits;
    last.start = start;
    last.own_mask = Some(again);
    Ok(true)
}

/// The sign mask's margins tried, in the one-step residual's trimmed rms, where the final
/// fit stopped at a kink of its loss ([`Kinks::unkinked`]): 2, 4 and 8 times
/// [`super::pwm_mask::MARGIN_SCALES`].
pub(crate) const KINK_SCALES: [f64; 3] = [6.0, 12.0, 24.0];

/// What [`Kinks::unkinked`] refits with: the logs, the weighting under the sign masks, the
/// model maker, the fit, and the parameters held at their start.
struct Kinks<'a, 'f> {
    experiments: &'a [crate::data::Experiment],
    weighting: &'a dyn Weighting,
    model: &'a dyn Fn(PwmInverter, VoltageInput) -> Result<PmsmPwm>,
    fit: &'a Fit<'f>,
    held: &'a [&'a str],
}

impl Kinks<'_, '_> {
    /// The stages' result from their final fits `last` at `input` ([`Self::unkinked`] on
    /// their own mask, or on `mask` where they have none).
    ///
    /// # Errors
    /// Those of [`Self::unkinked`].
    fn finish(
        &self,
        last: Final<'_, '_>,
        input: VoltageInput,
        mask: &super::pwm_mask::SignMask<'_>,
        notes: &mut Vec<String>,
    ) -> Result<(HoldFits, VoltageInput, PwmInverter)> {
        let on: &dyn Weighting = last.own_mask.as_ref().unwrap_or(mask);
        let fits = self.unkinked(last.fits, last.inverter, input, &last.names, &last.start, on, notes)?;
        Ok((fits, input, last.inverter))
    }

    /// The final fit `fits` (inverter, input, parameters `names` from `start`, on the sign
    /// mask `on`), or, where it stopped short of a minimum (`not_stationary`) and the
    /// criterion is not compensated for current noise, the first refit from its estimate on
    /// a wider sign mask at that estimate ([`KINK_SCALES`]) that stops at one.
    ///
    /// Why: the final mask weights out the periods whose predicted current is within 3× the
    /// residual's rms of zero; on a noise-free log that rms is micro-amperes, and a kept
    /// period whose current crosses zero just outside it turns its sign under a step of a
    /// few standard errors, a jump of `U_dc t_d / L` in the loss the Gauss–Newton model
    /// does not see. Measured: the independent 3 kHz IPM log with its drive's loop
    /// bandwidth given (`--speed-pll 2053.3`, the observer's matched pole) stopped there, a
    /// Gauss–Newton step of 8.1 standard errors still to go (exit 3). Under current noise
    /// the margin is the noise's, and the fit is left as it is. A refit that does not stop
    /// at a minimum either leaves `fits` as they were, warning and all.
    ///
    /// # Errors
    /// Those of the model, of [`super::pwm_mask::scaled_sign_mask`] but its
    /// [`Error::TooShort`] (no wider mask then) and of the fit.
    #[allow(clippy::too_many_arguments)]
    fn unkinked(
        &self,
        fits: HoldFits,
        inverter: PwmInverter,
        input: VoltageInput,
        names: &[&str],
        start: &[f64],
        on: &dyn Weighting,
        notes: &mut Vec<String>,
    ) -> Result<HoldFits> {
        let stopped = |f: &HoldFits| f.best.1.warnings.iter().any(|w| w.code == "not_stationary");
        if !stopped(&fits) || on.criterion_correction().is_some() {
            return Ok(fits);
        }
        let at = super::pwm_start::carried(Some(&fits.best.1), names, start, names);
        let model = (self.model)(inverter, input)?;
        let mut tried = Vec::with_capacity(KINK_SCALES.len());
        for scales in KINK_SCALES {
            let (mask, note) = match super::pwm_mask::scaled_sign_mask(
                self.experiments,
                &model,
                &at,
                self.weighting,
                scales,
            ) {
                Err(Error::TooShort { .. }) => break,
                other => other?,
            };
            tried.push(scales);
            let again = (self.fit)(self.experiments, inverter, input, &at, names, &mask, self.held)?;
            if !stopped(&again) {
                notes.push(format!(
                    "the final fit stopped short of a minimum where a kept period's predicted current turns its \
                     sign (not_stationary): refitted from its estimate on a wider {note}, and stopped at one"
                ));
                return Ok(again);
            }
        }
        notes.push(if tried.is_empty() {
            "the final fit stopped short of a minimum (not_stationary); a wider sign mask would leave a log too \
             short to refit it: kept as it stopped"
                .to_string()
        } else {
            format!(
                "the final fit stopped short of a minimum (not_stationary), and so did its refits on sign masks of \
                 {tried:?} × the residual's rms: kept as it stopped"
            )
        });
        Ok(fits)
    }
}
