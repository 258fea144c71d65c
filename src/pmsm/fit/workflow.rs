//! The whole PMSM workflow in one call, [`fit_pmsm`]: the options checked, then the fit
//! ([`super::base`]) or, with [`DeadTimeMask::Auto`], the fixed-point iteration of masked
//! fits ([`super::auto_mask`]). It sits above both and gives them itself as the refit that
//! confirms a suspected setup mistake, so that nothing below calls back up.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::model::mask::DeadTimeMask;
use crate::pmsm::options::PmsmFitOptions;

/// Fits a PMSM model to one or more logs of one motor (parameters shared unless listed in
/// `options.pem.per_experiment`).
///
/// # Errors
/// [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError::InvalidPolePairs) for `options.pole_pairs = 0`; [`Error::MissingChannel`]
/// for a log without `ud, uq, id, iq, w_m`;
/// [`Error::InvalidOption`] for no experiments, a start of the wrong length, an unknown
/// parameter name in `fixed`/`fixed_values`/`bounds`; [`Error::StartOutsideBounds`] for a
/// given start or fixed value outside the bounds;
/// [`Error::Numerical`] when the least-squares start cannot be computed (no excitation)
/// or gives a non-positive `R_s`/`L`; and every error of [`crate::estimate::fit`].
///
/// # Example
/// ```no_run
/// use greybox::pmsm::{fit_pmsm, PmsmFitOptions};
/// # fn main() -> greybox::Result<()> {
/// let log = greybox::pmsm::read_log("data/sample.csv.gz", &Default::default())?;
/// let fit = fit_pmsm(&[log], &PmsmFitOptions::new(4))?;
/// println!("{fit}");
/// println!("K_t = {:.5} N m/A", fit.derived("k_t").unwrap().value);
/// # Ok(()) }
/// ```
pub fn fit_pmsm(experiments: &[Experiment], options: &PmsmFitOptions) -> Result<PmsmFit> {
    crate::pmsm::log::signals::check_pole_pairs(options.pole_pairs)?;
    if experiments.is_empty() {
        return Err(Error::InvalidOption { option: "experiments".into(), reason: "no log given".into() });
    }
    let refit = |e: &[Experiment], o: &PmsmFitOptions| fit_pmsm(e, o).ok().map(|f| f.fit.loss);
    if options.inverter.and_then(|i| i.mask) == Some(DeadTimeMask::Auto) {
        return super::auto_mask::fit(experiments, options, &refit);
    }
    super::base::fit(experiments, options, &refit)
}
