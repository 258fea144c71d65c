//! The steady-state fit in the PMSM workflow (issue 32): asked for
//! ([`Dynamics::Steady`], `--model spm-steady|ipm-steady`) or chosen for a log whose sample
//! time the dynamic model cannot resolve ([`Dynamics::Auto`]), unless the log is a fast one
//! with its time column in other units ([`time_unit_mistake`]); the estimate of
//! [`steady_state`] as the report every fit gives ([`PmsmFit`]), so that tables, JSON,
//! batches (`--each`, per-log R_s and its temperature trend) and the Python package read
//! one format.

use super::steady_report::report;
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::FitResult;
use crate::pmsm::checks::detect::{max_turn, sample_time_facts, steady_warnings};
use crate::pmsm::checks::time_unit::time_unit_mistake;
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::linear::{SteadyEstimate, SteadyOptions, steady_state_of};
use crate::pmsm::log::DqLogs;
use crate::pmsm::log::longest_h;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::{VoltageHold, VoltageInput};
use crate::pmsm::model::kind::{MotorKind, smallest_inductance};
use crate::pmsm::options::{Dynamics, HoldChoice, PmsmFitOptions};

/// Context of the error that refuses a sample time the dynamic model cannot resolve (the
/// automatic choice takes the steady-state equations on it).
pub(crate) const SAMPLE_TIME: &str = "sample time";

/// Refuses the options the steady-state equations cannot honour, naming them; `why`, the
/// automatic choice's reason where it took the equations (the user did not ask for them:
/// the error says so, and how to keep the options).
///
/// # Errors
/// [`Error::InvalidOption`] (option `model`) listing them.
fn check_options(options: &PmsmFitOptions, why: Option<&str>) -> Result<()> {
    let pem = &options.pem;
    let given = [
        ("a start", options.start.is_some()),
        ("fixed parameters", !options.fixed.is_empty() || !options.fixed_values.is_empty()),
        ("bounds", !options.bounds.is_empty()),
        ("the reference voltage", options.input != VoltageInput::Terminal),
        ("the inverter model", options.inverter.is_some()),
        ("a voltage hold", options.hold != HoldChoice::Auto),
        ("a voltage limit", options.voltage_limit.is_some()),
        ("a prediction horizon", pem.horizon.is_some()),
        ("a prefilter", pem.prefilter.is_some()),
        ("the Huber loss", pem.huber.is_some()),
        ("output weights", pem.output_weights.is_some()),
    ];
    let bad: Vec<&str> = given.iter().filter(|(_, set)| *set).map(|(what, _)| *what).collect();
    if bad.is_empty() {
        return Ok(());
    }
    let equations = "the steady-state equations (instrumental variables on the steady samples of a slow log)";
    let reason = match why {
        None => format!("{equations} do not take {}", bad.join(", ")),
        Some(why) => format!(
            "the model was chosen automatically: {why}, so {equations} were to be fitted (--model {}), and they do \
             not take {}; leave those options out, or fit the dynamic model with --force",
            flag(options.model),
            bad.join(", ")
        ),
    };
    Err(Error::InvalidOption { option: "model".into(), reason })
}

/// The steady-state fit of `experiments` as a [`PmsmFit`]; `why` is the automatic choice's
/// reason (a note), `None` when it was asked for.
///
/// # Errors
/// [`Error::Numerical`] (context `sample time`) for a fast log whose time column is in ms
/// or µs (unless `options.force`); [`Error::InvalidOption`] for options the equations do
/// not take; those of [`steady_state`].
pub(crate) fn fit(dq: &DqLogs<'_>, options: &PmsmFitOptions, why: Option<String>) -> Result<PmsmFit> {
    fit_from(dq, options, why, None)
}

/// The steady-state equations' options that `options` give: the control period, the
/// parameters fitted per log and the cable resistance; the rest the equations' defaults.
/// Every steady-state fit of a dynamic fit's options takes these (the fit and the
/// agreement check alike).
pub(crate) fn steady_options(options: &PmsmFitOptions) -> SteadyOptions {
    SteadyOptions {
        control_period: options.control_period,
        per_experiment: options.pem.per_experiment.clone(),
        cable_resistance: options.cable_resistance,
        ..SteadyOptions::default()
    }
}

/// [`fit`] from the bare equations' estimate `bare` of the same logs with
/// [`steady_options`] of `options` when the caller has it (`None`: computed here), so a
/// caller that judged it first does not solve the equations twice.
///
/// # Errors
/// As [`fit`].
pub(crate) fn fit_from(
    dq: &DqLogs<'_>,
    options: &PmsmFitOptions,
    why: Option<String>,
    bare: Option<SteadyEstimate>,
) -> Result<PmsmFit> {
    let t0 = std::time::Instant::now();
    let experiments = dq.experiments();
    if !options.force
        && let Some(mistake) = time_unit_mistake(dq.views(), options.pole_pairs)
    {
        return Err(Error::Numerical {
            context: SAMPLE_TIME.into(),
            reason: format!(
                "{}this is a fast log, not one for the steady-state equations: {mistake}. --force fits it anyway",
                why.map_or(String::new(), |w| format!("{w}; but "))
            ),
        });
    }
    check_options(options, why.as_deref())?;
    let steady = steady_options(options);
    let est = match bare {
        Some(est) => est,
        None => steady_state_of(dq, options.pole_pairs, options.model, &steady)?,
    };
    let part = |e: &SteadyEstimate, logs: &[Experiment]| report(e, logs, options, 0.0, Vec::new());
    let checked = super::steady_checks::warnings(dq, options, &steady, &est, &part);
    let (est, widening) = super::steady_checks::widened(est, &checked.spread);
    let (est, truncation) = super::steady_checks::truncation(dq, options, &steady, est);
    let (est, accuracy) = super::steady_checks::accuracy(est);
    let checks = checked.warnings;
    let mut report = report(
        &est,
        experiments,
        options,
        t0.elapsed().as_secs_f64(),
        widening.into_iter().chain([truncation]).chain(accuracy).collect(),
    );
    let precise = super::steady_trust::warnings(&report, options);
    let warnings = gate(&est, &report).into_iter().chain(precise).chain(checks).chain(steady_warnings(
        dq.views(),
        options.pole_pairs,
        &report,
        options.read_scales,
    ));
    report.warnings = warnings.collect();
    let pmsm_notes = why.iter().map(|w| chosen_note(w, options.model)).collect();
    Ok(PmsmFit {
        report,
        pole_pairs: options.pole_pairs,
        hold: VoltageHold::Stator,
        input: VoltageInput::Terminal,
        cable_resistance: options.cable_resistance,
        inverter: None,
        pwm: None,
        hold_losses: Vec::new(),
        start_comparison: Vec::new(),
        // What the steady samples cannot tell is the diagnostics' advice (`steady_advice`).
        pmsm_advice: Vec::new(),
        pmsm_notes,
    })
}

/// The automatic choice after the dynamic fit refused the sample time (judged at the
/// least-squares start, which current noise biases): the steady-state fit when its own R_s
/// and smallest inductance confirm that the dynamic model cannot resolve the log, with the
/// note saying why; `None` (the refusal, which asks whether the time column is in ms,
/// stands) when the steady-state fit fails, e.g. on a fast log in ms ([`fit`]'s check), or
/// does not confirm it (a noisy fast log).
pub(crate) fn fit_if_slow(dq: &DqLogs<'_>, options: &PmsmFitOptions) -> Option<PmsmFit> {
    let fit = fit(dq, options, None).ok()?;
    let r_s = fit.parameter("r_s")?.value;
    let why = sample_time_facts(dq.views(), options.pole_pairs, r_s, smallest_inductance(&fit.report))?;
    Some(PmsmFit { pmsm_notes: vec![chosen_note(&why, options.model)], ..fit })
}

/// The note of the automatic choice, `why` the reason.
fn chosen_note(why: &str, kind: MotorKind) -> String {
    format!(
        "steady-state model chosen: {why}. The steady-state equations are fitted instead (--model {}; --force fits \
         the dynamic model anyway)",
        flag(kind)
    )
}

/// Whether the steady-state equations are what `options` ask for, or the automatic choice
/// to make for a log the rotor turns half a turn in (before any dynamic fit).
pub(crate) fn chosen_up_front(dq: &DqLogs<'_>, options: &PmsmFitOptions) -> Option<Option<String>> {
    match options.dynamics {
        Dynamics::Steady => Some(None),
        Dynamics::Auto if !options.force && !options.skip_setup_checks => {
            (max_turn(dq.views(), options.pole_pairs) >= std::f64::consts::PI).then(|| {
            Some(format!(
                "the rotor turns half an electrical turn or more within one sample (h = {:.4e} s{}), which no \
                     dynamic model of a held voltage can follow",
                longest_h(dq.views()),
                fastest_sample(dq.views())
            ))
            })
        }
        _ => None,
    }
}

/// Where the logs' speed is fastest, for a user to look at: `"; the fastest sample: row k
/// of log NAME, w_m = … rad/s"`, and where that value stands alone (both neighbours below
/// a tenth of it: a spike, not a drive's motion) the advice to check the cell; empty for
/// logs without samples.
fn fastest_sample(views: &[DqView<'_>]) -> String {
    let fastest = views
        .iter()
        .filter_map(|v| {
            let w = v.w_m();
            let (k, peak) = w.iter().map(|x| x.abs()).enumerate().max_by(|a, b| a.1.total_cmp(&b.1))?;
            Some((v, k, peak))
        })
        .max_by(|a, b| a.2.total_cmp(&b.2));
    let Some((v, k, peak)) = fastest else { return String::new() };
    let w = v.w_m();
    let beside =
        [k.checked_sub(1), Some(k + 1)].into_iter().flatten().filter_map(|j| w.get(j)).map(|x| x.abs());
    let alone = beside.clone().count() > 0 && beside.fold(0.0f64, f64::max) < 0.1 * peak;
    format!(
        "; the fastest sample: row {k} of log {}, w_m = {:.6e} rad/s{}",
        v.experiment().name(),
        w[k],
        if alone { ", over ten times its neighbours: a corrupt cell? mend it before fitting" } else { "" }
    )
}

/// The trust gate every fit passes ([`crate::estimate::gate`]): a poor fit with coloured
/// equation errors, non-positive parameters (each entry, per log too), non-finite
/// statistics, a singular information matrix.
fn gate(est: &SteadyEstimate, report: &FitResult) -> Vec<crate::estimate::Warning> {
    let implausible =
        (0..est.theta.len()).flat_map(|j| est.kind.implausible_entry(&est.names[j], est.theta[j])).collect();
    // A physical estimate whose 95 % interval reaches non-physical values.
    let undetermined = est.kind.undetermined(&report.parameters);
    let evidence = crate::estimate::gate::Evidence {
        remaining: Vec::new(),
        condition: (report.diagnostics.condition_number, Vec::new()),
        implausible,
        undetermined,
        white: est.whiteness.iter().map(|w| w.is_white(est.steady_samples)).collect(),
        poor_fit_advice: Some(
            "the steady samples do not follow the steady-state equations: check the columns, units and signs, \
             and whether the log is a fast one (its currents resolved between samples: the dynamic model)"
                .into(),
        ),
        parts: None,
    };
    crate::estimate::gate::warnings(&report.solver, &report.parameters, &report.fit, &evidence)
}

/// `kind`'s steady-state model name, e.g. `spm-steady`, for messages.
pub(crate) fn flag(kind: MotorKind) -> String {
    format!("{}-steady", kind.model_name().trim_start_matches("pmsm_"))
}
