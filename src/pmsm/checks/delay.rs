//! The delay check of a fit driven by the controller's reference: a wrong computational
//! delay biases every estimate (on a simulated drive log, `--delay 0` for a drive that
//! applies its reference one sample late gave `r_s` 18 % low with a 93 % fit and no other
//! warning), so the fits at the neighbouring delays decide.

use crate::data::Experiment;
use crate::estimate::Warning;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::options::{PmsmFitOptions, RefitLoss};

/// How many times lower the loss at a neighbouring delay must be for the check to speak (as
/// the pole-pair and column checks).
pub const DELAY_RATIO: f64 = 10.0;

/// Fewest samples of the part of each log on which a PWM fit's delays are compared (the
/// delay check); a log shorter than four times this, whose first quarter would be shorter,
/// is compared whole.
pub const PWM_DELAY_SAMPLES: usize = 16_384;

/// After a fit of loss `loss` driven by the reference with a given delay d: an untrusted
/// `delay` warning when the fit at `d − 1` or `d + 1` (from the least-squares start) has a
/// [`DELAY_RATIO`] times lower loss. `None` for the terminal voltage.
///
/// A fit through the switching-resolved PWM inverter compares the three delays on the first
/// quarter of each log (at least [`PWM_DELAY_SAMPLES`] samples), each fitted there from the
/// least-squares start through the same stages: its neighbours repeat every stage, and on
/// the whole shared 3 µs log they took 10–11 of the fit's 20 s. A wrong delay changes the
/// model's every period, so a part shows it as the whole does: on the first quarter of that
/// log a wrong `--delay 0` or `2` is named at about 10⁴–10⁵ times the right delay's loss.
pub(crate) fn warning(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    loss: f64,
    refit: RefitLoss<'_>,
) -> Option<Warning> {
    let VoltageInput::Reference { delay, advance, speed_pll } = options.input else {
        return None;
    };
    let pem = match options.pwm {
        Some(_) => crate::pmsm::options::stage_options(&options.pem),
        None => options.pem.clone(),
    };
    let at = |d: usize| PmsmFitOptions {
        input: VoltageInput::Reference { delay: d, advance, speed_pll },
        pem: pem.clone(),
        ..options.clone()
    };
    let part = options.pwm.and_then(|_| first_part(experiments));
    // The neighbours and, on a part, the given delay all at once (a PWM fit's neighbour
    // repeats its stages: two thirds of its time went to this check, one neighbour after the
    // other). A PWM neighbour's fits all stop at the stages' tolerance: its loss is then an
    // upper bound on its minimum, which is all a neighbour that would be named must beat (on
    // the shared 3 us log the wrong delay's final fits had taken 114 and 51 iterations, 18 s
    // of the check's 28). On a part, the given delay is fitted there in the same way.
    let logs = part.as_deref().unwrap_or(experiments);
    let fit_at = |d: Option<usize>| {
        let d = d?;
        Some((d, refit(logs, &PmsmFitOptions { start: None, skip_setup_checks: true, ..at(d) })?))
    };
    let ((given, earlier), later) = rayon::join(
        || {
            rayon::join(
                || if part.is_some() { fit_at(Some(delay)) } else { Some((delay, loss)) },
                || fit_at(delay.checked_sub(1)),
            )
        },
        || fit_at(delay.checked_add(1)),
    );
    let loss = given?.1;
    // The earlier delay first, as its own check would name it.
    let (other, times) = [earlier, later]
        .into_iter()
        .flatten()
        .find(|(_, alt)| alt * DELAY_RATIO < loss)
        .map(|(d, alt)| (d, loss / alt))?;
    Some(Warning::untrusted(
        "delay",
        format!(
            "a fit with a delay of {other} samples has a {times:.0} times lower loss than with the {delay} given{}: \
             the reference acts at another sample than the model assumes; check --delay (or --delay estimate)",
            if part.is_some() { " (each fitted on the first quarter of the log)" } else { "" }
        ),
    ))
}

/// The first quarter of every log when each holds at least [`PWM_DELAY_SAMPLES`] samples
/// there; `None` when a log is too short (the whole logs are then compared).
fn first_part(experiments: &[Experiment]) -> Option<Vec<Experiment>> {
    crate::pmsm::checks::segments::split_at_least(experiments, PWM_DELAY_SAMPLES).ok()?.into_iter().next()
}
