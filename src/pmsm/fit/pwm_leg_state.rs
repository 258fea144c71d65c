//! The leg state of a PWM fit whose width the unmasked fit estimated: the width held
//! against the sign on the masked samples, the sign refitted on its own mask before a width
//! is kept, and the criterion compensated for the measured current's noise, through the
//! smooth legs' own transition where they switch softly (docs/options.md, steps 5 and 6).

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::Weighting;
use crate::pmsm::fit::hold::HoldFits;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::pwm::{PmsmPwm, PwmInverter};

/// What [`leg_state`] fits with: the logs, the inverter of the stages (its width
/// estimated), the input, the weighting under the sign masks, the model maker, the fit and
/// the fit at the stages' tolerance.
pub(super) struct Sides<'a, 'w> {
    /// The logs fitted.
    pub(super) experiments: &'a [Experiment],
    /// The stages' inverter, its width `i_w` estimated.
    pub(super) pwm: &'a PwmInverter,
    /// The voltage input of the masked fits (the loop found).
    pub(super) input: VoltageInput,
    /// The weighting the sign masks weight out samples of.
    pub(super) weighting: &'w dyn Weighting,
    /// The model of an inverter and input.
    pub(super) model: &'a dyn Fn(PwmInverter, VoltageInput) -> Result<PmsmPwm>,
    /// A fit, converged.
    pub(super) fit: &'a Fit<'a>,
    /// A fit at the stages' tolerance.
    pub(super) stage_fit: &'a Fit<'a>,
}

/// The leg state of a fit whose width `i_w` the unmasked fit estimated (parameters `names`
/// from `theta`, the unmasked estimate): the masked fit at that width held, at the stages'
/// tolerance (converged here if the width is kept), unless the width is negligible against
/// the mask's margin ([`NEGLIGIBLE_WIDTH`]), where the sign is taken whatever the losses
/// say and that fit would only have been the sign fit's start (docs/performance.md). Where
/// the measured current's noise is material: the
/// sign with its criterion compensated, unless the width is wider than that noise makes of
/// a hard switch ([`NOISE_WIDTH`]) and the sign does not fit the masked samples
/// [`CONTRADICTS`] times better: then the legs switch softly, and the width is held with
/// its criterion compensated through the smooth legs' transition. Otherwise the width kept
/// or the sign taken by the lower loss on the masked samples; before a width is kept, the
/// sign is refitted on the mask at its own estimate where that differs ([`on_own_mask`]).
///
/// # Errors
/// Those of the fits, of [`compensate`] and of [`super::pwm_mask::sign_mask`].
pub(super) fn leg_state<'w, 'n>(
    sides: &Sides<'_, 'w>,
    names: &[&'n str],
    theta: &[f64],
    mask: &super::pwm_mask::SignMask<'w>,
    notes: &mut Vec<String>,
) -> Result<Final<'w, 'n>> {
    let Sides { pwm, input, fit, .. } = *sides;
    let i_w = names.iter().position(|n| *n == "i_w").map_or(f64::NAN, |j| theta[j]);
    // A width whose transition lies inside the band the mask weights out: the kept samples
    // see only its tail, `1 − (2/π) atan(i/i_w) < (2/π) i_w/i` beyond the mask's margin, and
    // a comparison of the losses there is decided by the few periods whose predicted current
    // nears zero inside a blanking (the sign flips at a piece's start, the width bends it
    // a little): on the shared low-drop log the sign led by 10 % from one unmasked estimate
    // and trailed by 26 % from another, and the width kept then left its parts disagreeing
    // (exit 3). Such a width is no property of the legs: the sign is taken, and the width's
    // masked fit is not made.
    let negligible = i_w < NEGLIGIBLE_WIDTH * mask.margin;
    let fits = if negligible {
        None
    } else {
        Some((sides.stage_fit)(sides.experiments, *pwm, input, theta, names, mask, &["i_w"])?)
    };
    // The width the unmasked fit finds holds the measured current's noise as well as the
    // legs' parasitic capacitances (a one-step prediction from a noisy current turns its
    // signs near zero as a wide leg state would), and the atan's slow tail then reaches the
    // kept samples: 0.05 A of noise gave i_w = 0.015 A and r_s 2.5 % low. Where that noise
    // is material the sign is taken (and its criterion compensated); otherwise the sign's
    // fit on the same samples decides, by the lower loss.
    let sign = PwmInverter { i_w: None, estimate_i_w: false, ..*pwm };
    let sign_names: Vec<&'n str> = names.iter().copied().filter(|n| *n != "i_w").collect();
    let width_fit = fits.as_ref().map(|f| &f.best.1);
    let sign_start = super::pwm_start::carried(width_fit, &sign_names, theta, names);
    let sign_fits = fit(sides.experiments, sign, input, &sign_start, &sign_names, mask, &[])?;
    let (width, hard) = (width_fit.map(|f| f.fit.loss), sign_fits.best.1.fit.loss);
    let noise = start_noise(sides, sign, &sign_fits, mask, notes)?;
    // A width the noise cannot make: the legs switch softly, which the sign does not
    // describe (on a 4 kHz log whose legs switch softly over 0.05 A, with 0.05 A of noise,
    // the sign's fit had R_s 6 % high at 6 standard errors); unless the sign fits the kept
    // samples CONTRADICTS times better than the width (on a noise-free log cut at 1.8 s, the
    // residual's rounding read as noise of 1.8e-7 A against an unmasked width of 1.2e-5 A,
    // the sign's loss 2000 times the lower; under 0.05 A of noise the two were within 0.2 %
    // of each other, on soft and hard legs alike). The width is then held, and its
    // criterion compensated through the smooth legs' own transition.
    let contradicted = width.is_some_and(|w| hard * CONTRADICTS < w);
    let soft =
        noise.as_ref().map(|n| n.1).filter(|rms| i_w > NOISE_WIDTH * rms && !contradicted && !negligible);
    if let (Some(rms), Some(fits)) = (soft, &fits) {
        let start = super::pwm_start::carried(Some(&fits.best.1), names, theta, names);
        if let Some((fits, m)) = compensate(sides, *pwm, fits, names, &start, mask, notes)? {
            notes.push(format!(
                "PWM leg state on the masked samples: the width i_w = {i_w:.3e} A of the unmasked fit, wider than \
                 the measured current's noise makes of a hard switch ({:.3e} A, σ = {rms:.3e} A per axis): the legs \
                 switch softly (parasitic capacitances); the width held, its criterion compensated",
                NOISE_WIDTH * rms
            ));
            return Ok(Final { fits, inverter: *pwm, names: names.to_vec(), start, own_mask: Some(m) });
        }
    }
    let compensated = match noise.filter(|_| soft.is_none()) {
        Some((correction, _)) => {
            let compensated = mask.compensated(correction);
            let at =
                super::pwm_start::carried(Some(&sign_fits.best.1), &sign_names, &sign_start, &sign_names);
            let fits = fit(sides.experiments, sign, input, &at, &sign_names, &compensated, &[])?;
            Some((fits, compensated))
        }
        None => None,
    };
    let noisy = compensated.is_some();
    let choice = |keep_sign: bool| match (keep_sign, noisy) {
        (true, true) => "the sign (the measured current's noise is material, and the width holds it)",
        (true, false) if negligible => "the sign (the width's transition lies inside the mask's margin)",
        (true, false) => "the sign",
        (false, _) => "the width",
    };
    let note = match width {
        Some(width) => format!(
            "PWM leg state on the masked samples: the width i_w = {i_w:.3e} A of the unmasked fit held (loss \
             {width:.6e}) against the sign ({hard:.6e}): "
        ),
        None => format!(
            "PWM leg state on the masked samples: the width i_w = {i_w:.3e} A of the unmasked fit, below \
             {NEGLIGIBLE_WIDTH} of the mask's margin {:.3e} A, not fitted there (the sign's loss {hard:.6e}): ",
            mask.margin
        ),
    };
    // The width's fits where they fit the masked samples better than the sign's (never for
    // a negligible width, not fitted).
    let better = fits.filter(|f| hard > f.best.1.fit.loss);
    Ok(match (compensated, better) {
        (Some((fits, m)), _) => {
            notes.push(note + choice(true));
            Final { fits, inverter: sign, names: sign_names, start: sign_start, own_mask: Some(m) }
        }
        (None, None) => {
            notes.push(note + choice(true));
            Final { fits: sign_fits, inverter: sign, names: sign_names, start: sign_start, own_mask: None }
        }
        (None, Some(fits)) => {
            let start = super::pwm_start::carried(Some(&fits.best.1), names, theta, names);
            let mut kept = "the width".to_string();
            if let Some(OwnMask { mask: again, fits: sign_again, start: at, note: mask_note }) =
                on_own_mask(sides, sign, &sign_fits, &sign_names, &sign_start, mask, &[])?
            {
                // Both on the sign's own samples, the width at the stages' tolerance (its
                // loss an upper bound on its minimum there).
                let width_again =
                    (sides.stage_fit)(sides.experiments, *pwm, input, &start, names, &again, &["i_w"])?;
                let (w, h) = (width_again.best.1.fit.loss, sign_again.best.1.fit.loss);
                kept = format!(
                    "the width; then on the sign's own mask ({mask_note}) the width {w:.6e} against the sign \
                     refitted {h:.6e}: {}",
                    choice(h <= w)
                );
                if h <= w {
                    notes.push(note + &kept);
                    return Ok(Final {
                        fits: sign_again,
                        inverter: sign,
                        names: sign_names,
                        start: at,
                        own_mask: Some(again),
                    });
                }
            }
            notes.push(note + &kept);
            // Converged from the stages' tolerance, on the width's samples.
            let fits = fit(sides.experiments, *pwm, input, &start, names, mask, &["i_w"])?;
            Final { fits, inverter: *pwm, names: names.to_vec(), start, own_mask: None }
        }
    })
}

/// The fits `fits` of `inverter` (parameters `names` from `start`, `held` held at their
/// start) refitted on the sign mask taken at their own estimate where that mask weights out
/// other samples than `mask`: the mask, the refit, its start (`fits`' estimate) and the
/// mask's note; `None` where the masks agree. Before a width is kept, the sign's fit on the
/// unmasked estimate's mask (which can stop far above its minimum where its own estimate
/// passes periods near zero that the mask keeps: on the shared 3 µs log cut at 1.75 s its
/// loss 2.4e-3 lost to the width's 4.8e-4, and the width's final fit then ended at 2.2e-2
/// with its parts disagreeing, exit 3); and the final fit of the stages.
///
/// # Errors
/// Those of the model, of [`super::pwm_mask::sign_mask`] and of the fit.
pub(super) fn on_own_mask<'w>(
    sides: &Sides<'_, 'w>,
    inverter: PwmInverter,
    fits: &HoldFits,
    names: &[&str],
    start: &[f64],
    mask: &super::pwm_mask::SignMask<'w>,
    held: &[&str],
) -> Result<Option<OwnMask<'w>>> {
    let at = super::pwm_start::carried(Some(&fits.best.1), names, start, names);
    let (again, note) = super::pwm_mask::sign_mask(
        sides.experiments,
        &(sides.model)(inverter, sides.input)?,
        &at,
        sides.weighting,
    )?;
    if again.same_samples(mask) {
        return Ok(None);
    }
    let fits = (sides.fit)(sides.experiments, inverter, sides.input, &at, names, &again, held)?;
    Ok(Some(OwnMask { mask: again, fits, start: at, note }))
}

/// Fits refitted on their own mask ([`on_own_mask`]).
pub(super) struct OwnMask<'w> {
    /// The mask at their estimate.
    pub(super) mask: super::pwm_mask::SignMask<'w>,
    /// The refit.
    pub(super) fits: HoldFits,
    /// The refit's start (n_θ values: the estimate the mask was taken at).
    pub(super) start: Vec<f64>,
    /// The mask's note.
    pub(super) note: String,
}

/// The final fit `fits` (inverter `inverter`, parameters `names`, from `start`; an
/// estimated width `i_w` held there) of a PWM model whose predictor restarts from the
/// measured current, refitted from its estimate with the criterion compensated for the
/// measured current's noise on that start where it is material ([`super::pwm_noise`];
/// through the smooth legs' own transition where the leg state has a width), with the
/// compensated mask; `None` otherwise (other gains, or noise below
/// [`super::pwm_noise::START_NOISE_SHARE`]).
///
/// # Errors
/// Those of [`super::pwm_noise::compensation`] and of the fit.
pub(super) fn compensate<'w>(
    sides: &Sides<'_, 'w>,
    inverter: PwmInverter,
    fits: &HoldFits,
    names: &[&str],
    start: &[f64],
    mask: &super::pwm_mask::SignMask<'w>,
    notes: &mut Vec<String>,
) -> Result<Option<(HoldFits, super::pwm_mask::SignMask<'w>)>> {
    let Some((correction, _)) = start_noise(sides, inverter, fits, mask, notes)? else { return Ok(None) };
    let start = super::pwm_start::carried(Some(&fits.best.1), names, start, names);
    let compensated = mask.compensated(correction);
    let held: &[&str] = if inverter.estimate_i_w { &["i_w"] } else { &[] };
    Ok(Some((
        (sides.fit)(sides.experiments, inverter, sides.input, &start, names, &compensated, held)?,
        compensated,
    )))
}

/// The criterion's compensation for the measured current's noise on the start of the
/// fits `fits` of `inverter` (on `mask`'s samples) and the noise's rms per axis \[A\], its
/// note in `notes`; `None` where the predictor does not restart from the measured current
/// or the noise is below [`super::pwm_noise::START_NOISE_SHARE`].
///
/// # Errors
/// Those of [`super::pwm_noise::compensation`].
fn start_noise(
    sides: &Sides<'_, '_>,
    inverter: PwmInverter,
    fits: &HoldFits,
    mask: &super::pwm_mask::SignMask<'_>,
    notes: &mut Vec<String>,
) -> Result<Option<(Box<dyn crate::estimate::CriterionCorrection>, f64)>> {
    if inverter.predictor_gain != Some(1.0) {
        return Ok(None);
    }
    let super::pwm_noise::StartCompensation { correction, note, rms } = super::pwm_noise::compensation(
        sides.experiments,
        &(sides.model)(inverter, sides.input)?,
        &fits.best.1,
        mask,
    )?;
    notes.push(note);
    Ok(correction.map(|c| (c, rms)))
}

/// The widest smooth leg state the measured current's noise makes of a hard switch, per
/// unit of its rms per axis σ: the expected sign of a current under Gaussian noise,
/// `erf(i / (√2 σ))`, has the slope `√(2/π) / σ` at zero, which `(2/π) atan(i / i_w)` has
/// at `i_w = σ √(2/π)`. On five logs whose inverter switches hard, with 0.05 A of noise per
/// phase (σ 0.041 A), the unmasked fit's width was 0.013–0.017 A (0.3–0.4 σ) in every seed;
/// on one whose legs switch softly over 0.05 A it was 0.052–0.056 A (1.3–1.4 σ).
pub(crate) const NOISE_WIDTH: f64 = 0.797_884_560_802_865_4;

/// A width `i_w` below this fraction of the sign mask's margin is taken for the sign
/// ([`leg_state`]): its leg state differs from the sign's by less than `(2/π) 0.1 ≈ 6.4 %`
/// on every kept sample. Measured ratios of the unmasked width to the margin: the three
/// shared noise-free PWM logs 0.007–0.032; their copies with 0.05 A of noise per phase
/// 0.054–0.077 (where the noise's own rule takes the sign as well); the drive simulator's
/// noise-free 4 kHz log whose legs switch softly over 0.05 A about 2e8 (the width kept).
/// Under noise a width the noise cannot make (above `NOISE_WIDTH σ`) is about 0.14 of the
/// margin or more (the margin is about 5.8 σ), so this rule never takes a soft leg's width.
pub(crate) const NEGLIGIBLE_WIDTH: f64 = 0.1;

/// How many times lower the sign's loss on the masked samples must be than the width's for
/// it to contradict a width wider than the noise makes (as the pole-pair and delay checks'
/// ratio): the sign is then taken.
const CONTRADICTS: f64 = 10.0;

/// The final fit of [`super::pwm_fit::stages`]: its fits, inverter, free parameters and start, and its mask
/// when that is not the stages' (compensated for the current's noise, or taken again at
/// the final estimate).
pub(super) struct Final<'w, 'n> {
    /// The final fits.
    pub(super) fits: HoldFits,
    /// Their inverter (its leg state chosen).
    pub(super) inverter: PwmInverter,
    /// Their free parameters, in the model's order (n_θ names).
    pub(super) names: Vec<&'n str>,
    /// Their start (n_θ values, in `names`' order).
    pub(super) start: Vec<f64>,
    /// Their mask where it is not the stages' (compensated, or taken at the sign's own
    /// estimate).
    pub(super) own_mask: Option<super::pwm_mask::SignMask<'w>>,
}

/// One PWM fit: (logs, inverter, input, start, names, weighting, parameters held at their
/// start).
pub(crate) type Fit<'a> = dyn Fn(&[Experiment], PwmInverter, VoltageInput, &[f64], &[&str], &dyn Weighting, &[&str]) -> Result<HoldFits>
    + 'a;
