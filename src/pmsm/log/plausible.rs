//! The plausibility limits of a log read (`options.force` skips them): its sample time
//! ([`MIN_SAMPLE_TIME`] … [`MAX_SAMPLE_TIME`], or [`MAX_STEADY_SAMPLE_TIME`] where the
//! steady-state equations may fit it) and the magnitude of its speeds, currents and
//! voltages ([`MAX_SPEED`], [`MAX_CURRENT`], [`MAX_VOLTAGE`]): a unit mistake or a corrupt
//! cell caught where it is read, named, rather than passed to a fit.

use std::path::Path;

use super::{CsvOptions, DqSource, MAX_SAMPLE_TIME, MAX_STEADY_SAMPLE_TIME, MIN_SAMPLE_TIME, TimeUnit};
use crate::data::Experiment;
use crate::error::{Error, Result};

/// `e` if its sample time and its values are plausible (or `options.force`).
///
/// # Errors
/// [`Error::ImplausibleSampleTime`] with the time unit that would explain h, if one does;
/// [`Error::ImplausibleValue`] ([`plausible_values`]).
pub(super) fn plausible(path: &Path, e: Experiment, options: &CsvOptions) -> Result<Experiment> {
    if options.force {
        return Ok(e);
    }
    let h = e.h();
    let max = if options.steady_state { MAX_STEADY_SAMPLE_TIME } else { MAX_SAMPLE_TIME };
    let range = MIN_SAMPLE_TIME..=max;
    if range.contains(&h) {
        return plausible_values(e, options);
    }
    let given = options.time_unit;
    let hint = [TimeUnit::S, TimeUnit::Ms, TimeUnit::Us]
        .into_iter()
        .filter(|&u| u != given)
        .map(|u| (u, h * given.per_second() / u.per_second()))
        .find(|(_, h)| range.contains(h))
        .map_or_else(
            || format!("a time column in other units than {}? ", given.name()),
            |(u, h)| format!("the time column in {0}? `--time-unit {0}` gives h = {h:e} s; ", u.name()),
        );
    // A log slower than the dynamic model's range but within the steady-state one: slow
    // telemetry, if its time column is right.
    let hint = if !options.steady_state && h > max && h <= MAX_STEADY_SAMPLE_TIME {
        format!("{hint}or slow telemetry, which `greybox fit` reads (the steady-state equations); ")
    } else {
        hint
    };
    Err(Error::ImplausibleSampleTime { path: path.to_path_buf(), h, min: MIN_SAMPLE_TIME, max, hint })
}

/// Largest plausible speed magnitude \[rad/s\] (some 10 million rpm).
pub const MAX_SPEED: f64 = 1e6;
/// Largest plausible current magnitude \[A\].
pub const MAX_CURRENT: f64 = 1e6;
/// Largest plausible voltage magnitude \[V\].
pub const MAX_VOLTAGE: f64 = 1e7;

/// `e` if no speed, current or voltage exceeds its plausible magnitude ([`MAX_SPEED`],
/// [`MAX_CURRENT`], [`MAX_VOLTAGE`]): a single corrupt cell (a long run of digits) would
/// otherwise pass as finite and turn the fit's choices (the steady-state model for a log
/// that seems to spin at 1e299 rad/s) into an error that names no row.
///
/// # Errors
/// [`Error::ImplausibleValue`] naming the column as the log names it (a dq channel of a
/// log read from its phases with the phase columns it comes from) and the first row.
fn plausible_values(e: Experiment, options: &CsvOptions) -> Result<Experiment> {
    use crate::pmsm::channel;
    let c = &options.columns;
    let phases = matches!(options.source, DqSource::Phases);
    let (currents, voltages) =
        (phases.then_some([&c.i_a, &c.i_b, &c.i_c]), phases.then_some([&c.u_a, &c.u_b, &c.u_c]));
    let checks = [
        (channel::W_M, &c.w_m, None, MAX_SPEED, "rad/s"),
        (channel::I_D, &c.i_d, currents, MAX_CURRENT, "A"),
        (channel::I_Q, &c.i_q, currents, MAX_CURRENT, "A"),
        (channel::U_D, &c.u_d, voltages, MAX_VOLTAGE, "V"),
        (channel::U_Q, &c.u_q, voltages, MAX_VOLTAGE, "V"),
        (channel::U_D_REF, &c.u_d_ref, None, MAX_VOLTAGE, "V"),
        (channel::U_Q_REF, &c.u_q_ref, None, MAX_VOLTAGE, "V"),
    ];
    for (name, column, from, limit, unit) in checks {
        let Ok(v) = e.channel(name) else { continue };
        if let Some((row, &value)) = v.iter().enumerate().find(|(_, x)| x.abs() > limit) {
            let column = match from {
                Some([a, b, c]) => format!("{column} (from {a}, {b}, {c})"),
                None => column.clone(),
            };
            return Err(Error::ImplausibleValue { column, row, value, limit, unit: unit.into() });
        }
    }
    Ok(e)
}
