//! `--method auto`, the default: output error, or instrumental variables where the output-error
//! fit finds the logged voltage's noise biasing it (`checks::voltage_bias`), with the voltage
//! hold checked again at the IV's own standard errors.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::FitResult;
use crate::pmsm::fit::iv::{Estimator, check_options, fit_pmsm_iv_after};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::fit::workflow::fit_pmsm;
use crate::pmsm::options::PmsmFitOptions;

/// Fits `experiments` with `estimator`: [`fit_pmsm`],
/// [`fit_pmsm_iv`](crate::pmsm::fit_pmsm_iv), or for [`Estimator::Auto`] the output-error
/// fit, followed by the IV fit from it ([`fit_pmsm_iv_after`]: at both holds where the
/// output-error losses hardly choose one, as for `fit_pmsm_iv`) with a note saying why when
/// the former carries the untrusted `voltage_noise_bias` warning and [`check_options`]
/// allows IV; where the IV fit fails, the output-error fit (untrusted by that warning) with
/// a note saying why.
///
/// # Errors
/// Those of [`fit_pmsm`]; of `fit_pmsm_iv` for [`Estimator::InstrumentalVariables`], its
/// reason then followed by the untrusted warnings of the output-error fit it started from.
pub fn fit_pmsm_by(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    estimator: Estimator,
) -> Result<PmsmFit> {
    if estimator == Estimator::InstrumentalVariables {
        // fit_pmsm_iv, with the output-error fit's warnings kept for its error.
        check_options(options)?;
        let oe = fit_pmsm(experiments, options)?;
        let untrusted: Vec<String> =
            oe.report.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.clone()).collect();
        return fit_pmsm_iv_after(oe, experiments, options).map_err(|e| named_by(e, &untrusted));
    }
    let oe = fit_pmsm(experiments, options)?;
    let biased =
        oe.report.warnings.iter().find(|w| w.code == "voltage_noise_bias").map(|w| w.message.clone());
    let Some(why) = biased.filter(|_| estimator == Estimator::Auto && check_options(options).is_ok()) else {
        return Ok(oe);
    };
    let (fit, note) = match fit_pmsm_iv_after(oe.clone(), experiments, options) {
        Ok(iv) => (
            iv,
            format!("--method auto took instrumental variables, for the output-error fit was biased: {why}"),
        ),
        // The remedy failed: the output-error fit, untrusted by the bias and naming what it
        // found (a speed in rpm on a noisy log made IV leave the positive parameters, exit 1
        // with nothing but "the instruments are too weak", where output error named it).
        Err(e) => (
            oe,
            format!(
                "--method auto would take instrumental variables, for the output-error fit was biased, but they \
                 failed ({e}): the output-error fit is reported, untrusted by its warnings"
            ),
        ),
    };
    let notes = fit.report.notes.iter().cloned().chain([note]).collect();
    Ok(PmsmFit { report: FitResult { notes, ..fit.report }, ..fit })
}

/// A failed IV fit's error `e` with the untrusted warnings `codes` of the output-error fit IV
/// started from appended, where there are any: what went wrong before the instruments did
/// (a speed in rpm, a wrong pole-pair count), which the bare numerical failure does not say.
/// Errors other than numerical ones are returned as they are.
fn named_by(e: Error, codes: &[String]) -> Error {
    match e {
        Error::Numerical { context, reason } if !codes.is_empty() => Error::Numerical {
            context,
            reason: format!(
                "{reason}; the output-error fit IV starts from is untrusted ({}): --method pem reports it with \
                 those warnings",
                codes.join(", ")
            ),
        },
        e => e,
    }
}
