//! `--method auto`, the default: output error, or instrumental variables where the output-error
//! fit finds the logged voltage's noise biasing it (`checks::voltage_bias`), with the voltage
//! hold checked again at the IV's own standard errors.

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::{FitResult, Warning};
use crate::pmsm::fit::hold::{DQ_DECISIVE, GIVE_THE_HOLD, largest_difference};
use crate::pmsm::fit::iv::{Estimator, check_options, fit_pmsm_iv, fit_pmsm_iv_after};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::fit::workflow::fit_pmsm;
use crate::pmsm::options::{HoldChoice, PmsmFitOptions};

/// Fits `experiments` with `estimator`: [`fit_pmsm`], [`fit_pmsm_iv`], or for
/// [`Estimator::Auto`] the output-error fit, followed by the IV fit from it
/// ([`fit_pmsm_iv_after`]) with a note saying why when the former carries the untrusted
/// `voltage_noise_bias` warning and [`check_options`] allows IV. Where the automatic hold
/// fitted both holds to losses within [`DQ_DECISIVE`] of each other, IV runs at both, and
/// estimates more than 3 combined standard errors apart make the fit untrusted
/// (`hold_ambiguous`): IV's errors are smaller than output error's, against which the hold
/// was chosen.
///
/// # Errors
/// Those of [`fit_pmsm`] and of [`fit_pmsm_iv`].
pub fn fit_pmsm_by(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    estimator: Estimator,
) -> Result<PmsmFit> {
    if estimator == Estimator::InstrumentalVariables {
        return fit_pmsm_iv(experiments, options);
    }
    let oe = fit_pmsm(experiments, options)?;
    let biased =
        oe.report.warnings.iter().find(|w| w.code == "voltage_noise_bias").map(|w| w.message.clone());
    let Some(why) = biased.filter(|_| estimator == Estimator::Auto && check_options(options).is_ok()) else {
        return Ok(oe);
    };
    let other = other_hold_fit(&oe, experiments, options)?;
    let iv = fit_pmsm_iv_after(oe, experiments, options)?;
    let note =
        format!("--method auto took instrumental variables, for the output-error fit was biased: {why}");
    let notes = iv.report.notes.iter().cloned().chain([note]).collect();
    let mut warnings = iv.report.warnings.clone();
    if !warnings.iter().any(|w| w.code == "hold_ambiguous") {
        warnings.extend(other.and_then(|other| hold_ambiguous(&iv, &other, options)));
    }
    Ok(PmsmFit { report: FitResult { notes, warnings, ..iv.report }, ..iv })
}

/// The IV fit at the hold the automatic choice did not take, when both were fitted and
/// their losses lie within [`DQ_DECISIVE`] of each other (the data hardly choose); `None`
/// otherwise.
///
/// # Errors
/// Those of [`fit_pmsm_iv_after`].
fn other_hold_fit(
    oe: &PmsmFit,
    experiments: &[Experiment],
    options: &PmsmFitOptions,
) -> Result<Option<PmsmFit>> {
    let [(a, la), (b, lb)] = oe.hold_losses[..] else { return Ok(None) };
    let close = (1.0 / DQ_DECISIVE..DQ_DECISIVE).contains(&(la / lb));
    if options.hold != HoldChoice::Auto || !close {
        return Ok(None);
    }
    let hold = if oe.hold == a { b } else { a };
    fit_pmsm_iv_after(PmsmFit { hold, ..oe.clone() }, experiments, options).map(Some)
}

/// An untrusted `hold_ambiguous` warning when the IV estimates at the two holds differ by
/// more than 3 combined standard errors in any parameter.
fn hold_ambiguous(iv: &PmsmFit, other: &PmsmFit, options: &PmsmFitOptions) -> Option<Warning> {
    let (name, z) = largest_difference(&iv.report, &other.report, options.model.parameter_names())?;
    (z > 3.0).then(|| {
        Warning::untrusted(
            "hold_ambiguous",
            format!(
                "the instrumental-variable estimates at the {} and {} voltage holds, whose output-error losses are \
                 close, differ in {name} by {z:.1} standard errors: the log does not say how the voltage was held; \
                 {GIVE_THE_HOLD}",
                iv.hold, other.hold
            ),
        )
    })
}
