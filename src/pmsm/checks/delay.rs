//! The delay check of a fit driven by the controller's reference: a wrong computational
//! delay biases every estimate (on a simulated drive log, `--delay 0` for a drive that
//! applies its reference one sample late gave `r_s` 18 % low with a 93 % fit and no other
//! warning), so the fits at the neighbouring delays decide.

use crate::data::Experiment;
use crate::estimate::Warning;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::options::{PmsmFitOptions, RefitReport};

/// How many times lower the loss at a neighbouring delay must be for the check to speak (as
/// the pole-pair and column checks).
pub const DELAY_RATIO: f64 = 10.0;

/// Fewest samples of the first quarter of each log on which a PWM fit's delays are
/// compared (the delay check); when any log's quarter would be shorter, the whole logs are
/// compared.
pub const PWM_DELAY_SAMPLES: usize = 16_384;

/// After a fit of loss `loss` driven by the reference with a given delay d: an untrusted
/// `delay` warning when the fit at `d − 1` or `d + 1` (from the least-squares start) has a
/// [`DELAY_RATIO`] times lower loss. `None` for the terminal voltage.
///
/// A fit through the switching-resolved PWM inverter is first screened by the averaged
/// inverter model (`screened`: [`screen`]'s answer, which the fit finds beside its own
/// stages; `None` for any other fit): where it ranks the given delay first, no neighbour is
/// fitted. Otherwise it compares the three delays on the first quarter of each log (at
/// least [`PWM_DELAY_SAMPLES`] samples), each fitted there from the least-squares start
/// through the same stages (its neighbours repeat every stage, and on the whole logs they
/// took half of the fit's time): a wrong delay changes the model's every period, so a part
/// shows it as the whole does. A neighbour the quarter would name is then confirmed on the
/// whole logs against `loss`, as without the quarter, so that a poor minimum of the given
/// delay's fit on the quarter cannot name a neighbour of a right delay (docs/performance.md
/// has the measured ratios).
pub(crate) fn warning(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    loss: f64,
    refit: RefitReport<'_>,
    screened: Option<bool>,
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
    // A PWM neighbour's fits all stop at the stages' tolerance: its loss is then an upper
    // bound on its minimum, which is all a neighbour that would be named must beat.
    let fit_at = |logs: &[Experiment], d: Option<usize>| {
        let d = d?;
        Some((d, refit(logs, &PmsmFitOptions { start: None, skip_setup_checks: true, ..at(d) })?.fit.loss))
    };
    // The earlier delay first, as its own check would name it.
    let beating = |found: [Option<(usize, f64)>; 2], loss: f64| {
        found.into_iter().flatten().find(|(_, alt)| alt * DELAY_RATIO < loss).map(|(d, alt)| (d, loss / alt))
    };
    if screened == Some(true) {
        return None;
    }
    let part = options.pwm.and_then(|_| first_part(experiments));
    let quarter = part.as_deref().and_then(|logs| {
        // The three at once: a PWM fit's neighbour repeats its stages.
        let [given, earlier, later] = side_by_side(delay, |d| fit_at(logs, d));
        given.map(|(_, g)| beating([earlier, later], g))
    });
    let (other, times) = match quarter {
        // Named on the quarter: confirmed on the whole logs.
        Some(Some((d, _))) => {
            (d, crate::pmsm::options::confirmed(refit, experiments, at(d), loss, DELAY_RATIO)?)
        }
        Some(None) => return None,
        // No quarter, or the given delay not fitted there: the whole logs.
        None => {
            let (earlier, later) = rayon::join(
                || fit_at(experiments, delay.checked_sub(1)),
                || fit_at(experiments, delay.checked_add(1)),
            );
            beating([earlier, later], loss)?
        }
    };
    Some(Warning::untrusted(
        "delay",
        format!(
            "a fit with a delay of {other} samples has a {times:.0} times lower loss than with the {delay} given{}: \
             the reference acts at another sample than the model assumes; check --delay (or --delay estimate)",
            if matches!(quarter, Some(Some(_))) {
                " (found on the first quarter of the log, confirmed on the whole)"
            } else {
                ""
            }
        ),
    ))
}

/// The screen of the delay check of a fit through the switching-resolved PWM inverter
/// driven by the reference with its setup checks ([`averaged_ranks_first`]); `None` for any
/// other fit. It needs no estimate: the fit runs it beside its stages.
pub(crate) fn screen(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    refit: RefitReport<'_>,
) -> Option<bool> {
    let VoltageInput::Reference { delay, .. } = options.input else { return None };
    (options.pwm.is_some() && !options.skip_setup_checks)
        .then(|| averaged_ranks_first(experiments, options, delay, refit))
}

/// The screen of a PWM fit's delay check: whether the averaged inverter model
/// (`--dead-time estimate --dead-time-mask auto`, the logged angle and speed, from the
/// least-squares start, on the whole logs) fits the given `delay` to a lower loss than each
/// neighbour it can fit (`false` when the given delay's fit fails). A wrong delay changes the
/// reference's every period, which the averaged model sees as the switching-resolved one
/// does: on the three shared motulator PWM logs its losses at the neighbours of the right
/// delay are 44 … 5800 times higher, on the drive simulator's noise-free 4 kHz log 220 and
/// 240 times, and with 0.05 A of noise per phase there 1.10 and 1.27 times, still ranked.
/// Then the PWM neighbours, whose stages cost a fit each, are not fitted. The premise,
/// measured on those logs and not proven: a neighbour the PWM model would find
/// [`DELAY_RATIO`] times better is one the averaged model ranks first.
fn averaged_ranks_first(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    delay: usize,
    refit: RefitReport<'_>,
) -> bool {
    let VoltageInput::Reference { advance, .. } = options.input else { return false };
    let averaged = crate::pmsm::options::averaged_inverter(options);
    let at = |d: usize| PmsmFitOptions {
        input: VoltageInput::Reference { delay: d, advance, speed_pll: None },
        ..averaged.clone()
    };
    let [given, earlier, later] =
        side_by_side(delay, |d| d.and_then(|d| refit(experiments, &at(d)).map(|f| f.fit.loss)));
    given.is_some_and(|g| [earlier, later].into_iter().flatten().all(|l| l > g))
}

/// `fit` at the given `delay`, the one before and the one after (`None` below 0), side by
/// side: `[given, earlier, later]`.
fn side_by_side<T: Send>(delay: usize, fit: impl Fn(Option<usize>) -> Option<T> + Sync) -> [Option<T>; 3] {
    let ((given, earlier), later) = rayon::join(
        || rayon::join(|| fit(Some(delay)), || fit(delay.checked_sub(1))),
        || fit(delay.checked_add(1)),
    );
    [given, earlier, later]
}

/// The first quarter of every log when each holds at least [`PWM_DELAY_SAMPLES`] samples
/// there; `None` when a log is too short (the whole logs are then compared).
fn first_part(experiments: &[Experiment]) -> Option<Vec<Experiment>> {
    crate::pmsm::checks::segments::split_at_least(experiments, PWM_DELAY_SAMPLES).ok()?.into_iter().next()
}
