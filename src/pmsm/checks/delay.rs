//! The delay check of a fit driven by the controller's reference: a wrong computational
//! delay biases every estimate (on a simulated drive log, `--delay 0` for a drive that
//! applies its reference one sample late gave `r_s` 18 % low with a 93 % fit and no other
//! warning), so the fits at the neighbouring delays decide.

use crate::data::Experiment;
use crate::estimate::Warning;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::options::{PmsmFitOptions, RefitLoss, confirmed};

/// How many times lower the loss at a neighbouring delay must be for the check to speak (as
/// the pole-pair and column checks).
pub const DELAY_RATIO: f64 = 10.0;

/// After a fit of loss `loss` driven by the reference with a given delay d: an untrusted
/// `delay` warning when the fit at `d − 1` or `d + 1` (from the least-squares start) has a
/// [`DELAY_RATIO`] times lower loss. `None` for the terminal voltage.
pub(crate) fn warning(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    loss: f64,
    refit: RefitLoss<'_>,
) -> Option<Warning> {
    let VoltageInput::Reference { delay, advance, speed_pll } = options.input else {
        return None;
    };
    // Both neighbours at once (a PWM fit's neighbour repeats its stages: two thirds of its
    // time went to this check, one neighbour after the other); the earlier delay first. A
    // PWM neighbour's fits all stop at the stages' tolerance: its loss is then an upper
    // bound on its minimum, which is all a neighbour that would be named must beat (on the
    // shared 3 us log the wrong delay's final fits had taken 114 and 51 iterations, 18 s of
    // the check's 28).
    let confirm = |d: Option<usize>| {
        let d = d?;
        let input = VoltageInput::Reference { delay: d, advance, speed_pll };
        let pem = match options.pwm {
            Some(_) => crate::pmsm::options::stage_options(&options.pem),
            None => options.pem.clone(),
        };
        let times = confirmed(
            refit,
            experiments,
            PmsmFitOptions { input, pem, ..options.clone() },
            loss,
            DELAY_RATIO,
        )?;
        Some((d, times))
    };
    let (earlier, later) = rayon::join(|| confirm(delay.checked_sub(1)), || confirm(delay.checked_add(1)));
    let (other, times) = earlier.or(later)?;
    Some(Warning::untrusted(
        "delay",
        format!(
            "a fit with a delay of {other} samples has a {times:.0} times lower loss than with the {delay} given: the \
             reference acts at another sample than the model assumes; check --delay (or --delay estimate)"
        ),
    ))
}
