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
/// as for [`fit_pmsm_iv`]) with a note saying why when the former carries the untrusted
/// `voltage_noise_bias` warning and [`check_options`] allows IV.
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
    let iv = fit_pmsm_iv_after(oe, experiments, options)?;
    let note =
        format!("--method auto took instrumental variables, for the output-error fit was biased: {why}");
    let notes = iv.report.notes.iter().cloned().chain([note]).collect();
    Ok(PmsmFit { report: FitResult { notes, ..iv.report }, ..iv })
}
