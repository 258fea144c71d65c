//! `--pole-pairs auto`: the pole-pair number chosen by prediction-error fits of the
//! least-squares scan's best candidates.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::checks::pole_pairs::pole_pair_losses;
use crate::pmsm::options::PmsmFitOptions;

/// `(n_p, runner-up loss / winner's loss, every (n_p, loss) fitted)`.
pub type AutoPolePairs = (u32, f64, Vec<(u32, f64)>);

/// Least-squares candidates that `--pole-pairs auto` fits by the prediction-error method.
pub const AUTO_CANDIDATES: usize = 3;

/// `--pole-pairs auto`: the [`AUTO_CANDIDATES`] pole-pair numbers of lowest least-squares
/// loss are fitted with `options` (their `pole_pairs` replaced), and the lowest
/// prediction-error loss wins (the regression alone is fooled by current noise). Returns
/// `n_p`, the runner-up's loss over the winner's, and every `(n_p, loss)` fitted.
///
/// # Errors
/// Those of [`pole_pair_losses`]; [`Error::Numerical`] when no candidate can be fitted.
pub fn choose_pole_pairs_by_fit(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
) -> Result<AutoPolePairs> {
    let mut ls = pole_pair_losses(experiments, options.model, options.input)?;
    ls.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut fitted: Vec<(u32, f64)> = ls
        .iter()
        .take(AUTO_CANDIDATES)
        .filter_map(|&(n, _)| {
            let o = PmsmFitOptions { pole_pairs: n, skip_setup_checks: true, ..options.clone() };
            let fit = super::workflow::fit_pmsm(experiments, &o).ok()?;
            fit.solver.success.then_some((n, fit.fit.loss))
        })
        .collect();
    fitted.sort_by(|a, b| a.1.total_cmp(&b.1));
    match fitted.as_slice() {
        [(n, best), rest @ ..] => {
            let ratio = rest.first().map_or(f64::INFINITY, |r| r.1 / best);
            Ok((*n, ratio, fitted.clone()))
        }
        [] => Err(Error::Numerical {
            context: "pole pairs".into(),
            reason: "no candidate pole-pair number gives a converged fit".into(),
        }),
    }
}
