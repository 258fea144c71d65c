//! The late-voltage check confirmed by a refit (issue 43: no wrong answer with exit 0).
//!
//! A controller's reference logged as if it were the terminal voltage acts one sample
//! later than the model assumes. Noise-free, the voltage-equation residual follows the
//! voltage's change (correlation 0.97, slope 0.99 on the shared servo log) and the residual
//! check of [`crate::pmsm::checks::advice`] names it. With 0.01 A of current noise the
//! differentiated noise in that residual takes the correlation to 0.17 and the check was
//! silent, while the output-error fit put `l_s` 0.35 % high at 6.5 standard errors with
//! exit 0 (0.1 A: correlation 0.015, `l_s` +0.34 % at z 6.0, exit 0). The slope stays near 1
//! (0.98, 0.81): where it exceeds [`LATE_SLOPE`](crate::pmsm::thresholds::LATE_SLOPE)
//! without the correlation on every log, the logs are refitted with their voltage as a
//! controller's reference ([`VoltageInput::REFERENCE`]: applied one sample later, with the
//! modulator's 1.5 ω_e h angle advance, held in the stator frame), and a loss lower by more
//! than [`LATE_Z`] standard deviations of its noise ([`noise_z_against`], Vuong's test of
//! non-nested models) makes the fit untrusted. On the logged terminal voltage with white
//! residuals the check does not run (a late voltage leaves coloured residuals, as the dead
//! time does, [`crate::pmsm::checks::advice::dead_time_can_speak`]).
//!
//! Not covered: a joint fit in which only some logs are suspect (one input for all logs:
//! the right logs refitted as late would mask the late one), and fits without the setup
//! checks (`skip_setup_checks`); the residual check still runs on both.

use crate::data::{Channel, Experiment};
use crate::estimate::{FitResult, Warning};
use crate::pmsm::log::signals::channel;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::options::{HoldChoice, PmsmFitOptions, RefitReport};

use super::hold::noise_z_against;

/// Standard deviations of its noise by which the late hypothesis' loss must be lower than
/// the fit's for the check to speak (one-sided; 3 leaves 0.13 % to chance where the two
/// models fitted the samples equally well, and a right terminal voltage makes the late one
/// worse, not equal).
pub const LATE_Z: f64 = 3.0;

/// After a fit `fit` of `experiments` with `options` whose late-voltage residual check
/// suspects every log ([`crate::pmsm::checks::advice::late_voltage_advice`]; the caller
/// asks only then): an untrusted `voltage_late` warning when the refit (`refit`, without
/// setup checks) of the logs with their voltage as a controller's reference
/// ([`VoltageInput::REFERENCE`], the stator hold, no voltage limit, whose weights would
/// drop samples from its loss) has a loss lower by more than [`LATE_Z`] standard
/// deviations. The refit starts from the least-squares estimate, or from the fit's own
/// start where parameters are fixed (so that they keep their values). `None` otherwise:
/// for a modelled voltage (a reference, an inverter model), white residuals, fits without
/// the setup checks, or a failed refit.
pub(crate) fn warning(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    fit: &FitResult,
    refit: RefitReport<'_>,
) -> Option<Warning> {
    let terminal =
        options.input == VoltageInput::Terminal && options.inverter.is_none() && options.pwm.is_none();
    if !terminal || options.skip_setup_checks || fit.uncertainty.white() {
        return None;
    }
    let late: Vec<Experiment> =
        experiments.iter().map(as_reference).collect::<crate::error::Result<_>>().ok()?;
    let other = PmsmFitOptions {
        input: VoltageInput::REFERENCE,
        hold: HoldChoice::Stator,
        voltage_limit: None,
        start: if options.fixed.is_empty() { None } else { options.start.clone() },
        skip_setup_checks: true,
        ..options.clone()
    };
    let alt = refit(&late, &other)?.fit.loss;
    let z = noise_z_against(fit, alt)?;
    (alt < fit.fit.loss && z > LATE_Z).then(|| {
        Warning::untrusted(
            "voltage_late",
            format!(
                "the voltage acts later than the model assumes, as a controller's reference does: the logs \
                 refitted with their voltage as a reference (applied one sample later, with the modulator's \
                 angle advance) have a {:.3} times lower loss ({z:.1} \
                 standard deviations of its noise); fit the reference (--voltage reference --delay estimate, \
                 with --col-ud-ref and --col-uq-ref naming the columns that hold it, docs/options.md) or log the \
                 terminal voltage",
                fit.fit.loss / alt
            ),
        )
    })
}

/// The log `e` with its voltage `ud, uq` also as the controller's reference `ud_ref, uq_ref`
/// (the values shared, not copied).
fn as_reference(e: &Experiment) -> crate::error::Result<Experiment> {
    let mut out = e.clone();
    for (from, to) in [(channel::U_D, channel::U_D_REF), (channel::U_Q, channel::U_Q_REF)] {
        let unit = e.get(from).map(|c| c.unit.clone()).unwrap_or_default();
        out = out.with_channel(Channel { name: to.into(), unit, values: e.values(from)?.clone() })?;
    }
    Ok(out)
}
