//! The choice between the two voltage holds (MODEL.md §4) and the advice when the data do
//! not settle it.

use super::interval::VoltageHold;
use crate::estimate::FitResult;

/// Factor by which the dq hold's loss must be lower than the stator hold's for
/// [`HoldChoice::Auto`] to choose it.
pub const DQ_DECISIVE: f64 = 2.0;

pub(crate) fn hold_ambiguity(
    best: &FitResult,
    hold: VoltageHold,
    others: &[(VoltageHold, FitResult)],
    names: &[&str],
) -> Option<String> {
    let (other_hold, other) = others.first()?;
    let ratio = other.fit.loss / best.fit.loss;
    if ratio.is_nan() || !(1.0 / DQ_DECISIVE..DQ_DECISIVE).contains(&ratio) {
        return None;
    }
    // Differ by more than their joint uncertainty (3 combined standard errors).
    let (name, z) = names
        .iter()
        .filter_map(|n| {
            let (a, b) = (best.parameter(n)?, other.parameter(n)?);
            Some((*n, ((a.value - b.value) / a.std_error.hypot(b.std_error)).abs()))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    (z > 3.0).then(|| {
        format!(
            "the {hold} and {other_hold} voltage holds fit almost equally well (loss ratio {ratio:.3}) but their {name} \
             differs by {z:.0} standard errors: the log does not say how the voltage was held; a real \
             inverter holds it in the stator frame (--hold stator); this fit used the {hold} hold"
        )
    })
}
