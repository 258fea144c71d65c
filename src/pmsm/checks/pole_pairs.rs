//! The pole-pair number: `--pole-pairs auto` and the check of a given `n_p`, by the
//! least-squares losses of the voltage equations at every candidate (thesis 5.2.1), from
//! one Gram matrix of the scan ([`crate::pmsm::checks::detect`]), and where the scan
//! disagrees with the count given, by the prediction-error fit at the scan's count.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::Warning;
use crate::pmsm::checks::detect::loss_at;
use crate::pmsm::checks::scan::scan_gram;
use crate::pmsm::log::DqLogs;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::options::{PmsmFitOptions, RefitReport, nested_loss};
use nalgebra::DMatrix;

/// Candidates of `--pole-pairs auto` and of the pole-pair check.
pub const POLE_PAIR_CANDIDATES: std::ops::RangeInclusive<u32> = 1..=32;
/// A given `n_p` whose loss exceeds another candidate's by this factor is flagged.
pub const POLE_PAIR_RATIO: f64 = 10.0;
/// Or, below [`POLE_PAIR_RATIO`], where the other candidate's loss is lower by this many
/// standard deviations of the losses' difference under the residuals' noise (one-sided;
/// Vuong's test of non-nested models, *Econometrica* 57 (1989) 307–333, as the holds' and
/// the late voltage's checks take it): noise shrinks the ratio of a wrong `n_p`'s loss to
/// the right one's (9.7 on a set-aside noisy IPM log fitted at 4 of its 3 pole pairs,
/// `l_q` 25 % low with exit 0), not its significance.
pub const POLE_PAIR_Z: f64 = 3.0;
/// Every candidate's `(n_p, loss)` from a [`scan_gram`].
fn losses_from(g: &DMatrix<f64>, kind: MotorKind) -> Vec<(u32, f64)> {
    POLE_PAIR_CANDIDATES.filter_map(|n| loss_at(g, kind, n).map(|(l, _)| (n, l))).collect()
}

/// The least-squares loss of the voltage equations at every candidate pole-pair number in
/// [`POLE_PAIR_CANDIDATES`], `(n_p, loss [V²])`, for the voltage `input`.
///
/// # Errors
/// Those of the regression scan (a missing channel, a log too short for the prefilter).
pub fn pole_pair_losses(
    experiments: &[Experiment],
    kind: MotorKind,
    input: VoltageInput,
) -> Result<Vec<(u32, f64)>> {
    Ok(losses_from(&scan_gram(DqLogs::try_new(experiments)?.views(), input)?, kind))
}

/// `--pole-pairs auto`: the candidate of lowest loss and the ratio of the runner-up's loss
/// to it (large: decisive).
///
/// # Errors
/// Those of [`pole_pair_losses`]; [`Error::Numerical`] when no candidate has a loss (no
/// excitation).
pub fn choose_pole_pairs(
    experiments: &[Experiment],
    kind: MotorKind,
    input: VoltageInput,
) -> Result<(u32, f64)> {
    let mut losses = pole_pair_losses(experiments, kind, input)?;
    losses.sort_by(|a, b| a.1.total_cmp(&b.1));
    match losses.as_slice() {
        [(n, best), (_, second), ..] => Ok((*n, second / best)),
        [(n, _)] => Ok((*n, f64::INFINITY)),
        [] => Err(Error::Numerical {
            context: "pole pairs".into(),
            reason: "no candidate can be regressed (the log does not excite the voltage equations)".into(),
        }),
    }
}

/// The pole-pair check: when the least-squares scan prefers another `n_p`, by any factor,
/// the prediction-error fit at that `n_p` decides (the scan alone is fooled by current noise
/// in `di/dt`); a warning names it when its loss is [`POLE_PAIR_RATIO`] times lower, or lower
/// by [`POLE_PAIR_Z`] standard deviations of its noise (`noise_z`, the fit's own: its
/// residuals' noise against the other loss). The
/// scan's own ratio is no test: an interior-magnet regression absorbs much of a wrong `n_p`
/// into its inductances and `k_e` (on a gym-electric-motor IPM log with 3 pole pairs fitted
/// at 4 with `--hold dq` the scan preferred 3 by less than 10, while the fits' losses
/// differ 7.7·10⁸ times; the fit at 4 left with exit 0 and `l_q` 21 % low). `g` is the
/// [`scan_gram`] of `experiments`.
pub(crate) fn pole_pair_warning(
    g: &DMatrix<f64>,
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    loss: f64,
    noise_z: &dyn Fn(f64) -> Option<f64>,
    refit: RefitReport<'_>,
) -> Option<Warning> {
    let losses = losses_from(g, options.model);
    let given = losses.iter().find(|(n, _)| *n == options.pole_pairs)?.1;
    let &(nb, lb) = losses.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
    if nb == options.pole_pairs || given <= lb {
        return None;
    }
    let alt = nested_loss(refit, experiments, PmsmFitOptions { pole_pairs: nb, ..options.clone() })?;
    let check = "check -p (or a speed logged in the electrical frame: --speed-frame electrical)";
    let n_p = options.pole_pairs;
    let message = if alt * POLE_PAIR_RATIO < loss {
        format!(
            "a fit with {nb} pole pairs has a {:.0} times lower loss than with the {n_p} given: {check}",
            loss / alt
        )
    } else {
        let z = noise_z(alt).filter(|z| alt < loss && *z > POLE_PAIR_Z)?;
        format!(
            "a fit with {nb} pole pairs has a {:.2} times lower loss than with the {n_p} given, {z:.0} standard \
             deviations of the residuals' noise: {check}",
            loss / alt
        )
    };
    Some(Warning::untrusted("pole_pairs", message))
}
