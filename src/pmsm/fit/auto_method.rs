//! `--method auto`, the default: output error, or instrumental variables where the output-error
//! fit finds the logged voltage's noise biasing it (`checks::voltage_bias`), with the voltage
//! hold checked again at the IV's own standard errors.

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::FitResult;
use crate::pmsm::fit::iv::{Estimator, check_options, fit_pmsm_iv, fit_pmsm_iv_after};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::fit::workflow::fit_pmsm;
use crate::pmsm::options::PmsmFitOptions;

/// Fits `experiments` with `estimator`: [`fit_pmsm`], [`fit_pmsm_iv`], or for
/// [`Estimator::Auto`] the output-error fit, followed by the IV fit from it
/// ([`fit_pmsm_iv_after`]: at both holds where the output-error losses hardly choose one,
/// as for [`fit_pmsm_iv`]) with a note saying why when
/// the former carries the untrusted `voltage_noise_bias` warning and [`check_options`]
/// allows IV; where the IV fit fails, the output-error fit (untrusted by that warning) with
/// a note saying why.
///
/// # Errors
/// Those of [`fit_pmsm`] and, for [`Estimator::InstrumentalVariables`], of [`fit_pmsm_iv`].
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
