//! The steady-state fit in the PMSM workflow (issue 32): asked for
//! ([`Dynamics::Steady`], `--model spm-steady|ipm-steady`) or chosen for a log whose sample
//! time the dynamic model cannot resolve ([`Dynamics::Auto`]), unless the log is a fast one
//! with its time column in other units ([`time_unit_mistake`]); the estimate of
//! [`steady_state`] as the report every fit gives ([`PmsmFit`]), so that tables, JSON,
//! batches (`--each`, per-log R_s and its temperature trend) and the Python package read
//! one format.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::diagnostics::{DiagnosticThresholds, diagnose};
use crate::estimate::{
    FitResult, FitStatistics, ParameterEstimate, SolverReport, Termination, Timing, metrics,
};
use crate::model::DerivedEstimate;
use crate::pmsm::checks::detect::{max_turn, sample_time_facts, steady_warnings};
use crate::pmsm::checks::time_unit::time_unit_mistake;
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::linear::{PERIOD_TERM, SteadyEstimate, SteadyOptions, steady_advice, steady_state_of};
use crate::pmsm::log::DqLogs;
use crate::pmsm::log::longest_h;
use crate::pmsm::model::interval::{SQRT_2_3, VoltageHold, VoltageInput};
use crate::pmsm::model::kind::{MotorKind, derived, smallest_inductance};
use crate::pmsm::options::{Dynamics, HoldChoice, PmsmFitOptions};
use nalgebra::DMatrix;

/// Context of the error that refuses a sample time the dynamic model cannot resolve (the
/// automatic choice takes the steady-state equations on it).
pub(crate) const SAMPLE_TIME: &str = "sample time";

/// Refuses the options the steady-state equations cannot honour, naming them.
///
/// # Errors
/// [`Error::InvalidOption`] (option `model`) listing them.
fn check_options(options: &PmsmFitOptions) -> Result<()> {
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
    Err(Error::InvalidOption {
        option: "model".into(),
        reason: format!(
            "the steady-state equations (instrumental variables on the steady samples of a slow log) do not take {}",
            bad.join(", ")
        ),
    })
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
    check_options(options)?;
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
                "the rotor turns half an electrical turn or more within one sample (h = {:.4e} s), which no \
                     dynamic model of a held voltage can follow",
                longest_h(dq.views())
            ))
            })
        }
        _ => None,
    }
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

/// The estimate `est` of `experiments` as the generic report (parameters with intervals,
/// derived quantities and temperatures, diagnostics, goodness of fit over the steady
/// samples, the IV iterations as the solver), `fit_s` \[s\] the time it took, `widening`
/// the notes on intervals widened (by the parts' spread, by the truncation error).
fn report(
    est: &SteadyEstimate,
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    fit_s: f64,
    widening: Vec<String>,
) -> FitResult {
    let n = est.theta.len();
    let label = |j: usize| match est.experiment[j].is_none() && est.names[j] == PERIOD_TERM {
        true => PERIOD_SHOWN.to_string(),
        false => super::steady_checks::label(est, j),
    };
    let relative: Vec<f64> = (0..n).map(|j| 100.0 * est.std_error[j] / est.theta[j].abs()).collect();
    let parameters: Vec<ParameterEstimate> = (0..n)
        .map(|j| {
            let p = ParameterEstimate {
                name: est.names[j].clone(),
                unit: est.units[j].clone(),
                value: est.theta[j],
                std_error: est.std_error[j],
                std_error_white: est.std_error_white[j],
                ci95: [est.theta[j] - est.ci95[j], est.theta[j] + est.ci95[j]],
                // The error index belongs to the output-error criterion.
                error_index_percent: f64::NAN,
                fixed: false,
                nuisance: false,
                at_bound: false,
                experiment: est.experiment[j].clone(),
                start: est.theta[j],
            };
            if est.names[j] == PERIOD_TERM { control_period(p) } else { p }
        })
        .collect();
    let cov = DMatrix::from_fn(n, n, |a, b| est.correlation[a][b] * est.std_error[a] * est.std_error[b]);
    // Relative information: by θ; the period term h_c2 by 12/ω_e² at the logs' top
    // electrical speed, where its back-EMF term (ω_e h_c)²/12 is the whole back-EMF, so that
    // its relative error is that of the back-EMF it corrects, as K_e's is (its estimate is
    // about 0 on a log whose voltage is held in dq; scaled by its own standard error, a
    // precise fit of such a log read as singular: condition 2.5e12 on every 80th row of a
    // shared 8 kHz log of moves whose estimates lie within 1.1 standard errors).
    let w_e_top = crate::pmsm::log::DqLogs::try_new(experiments)
        .map_or(0.0, |dq| dq.views().iter().flat_map(|v| v.w_m().iter()).fold(0.0f64, |a, w| a.max(w.abs())))
        * f64::from(options.pole_pairs);
    let size = |j: usize| match (est.names[j] == PERIOD_TERM, w_e_top > 0.0 && w_e_top.is_finite()) {
        (true, true) => 12.0 / (w_e_top * w_e_top),
        (true, false) => est.theta[j].abs().max(est.std_error[j]),
        (false, _) => est.theta[j],
    };
    let info_rel = cov
        .try_inverse()
        .map(|m| DMatrix::from_fn(n, n, |a, b| m[(a, b)] * size(a) * size(b)))
        .unwrap_or_else(|| DMatrix::from_element(n, n, f64::NAN));
    let labels: Vec<String> = (0..n).map(label).collect();
    let kind = est.kind;
    let diagnostics = diagnose(
        &info_rel,
        &labels,
        &relative,
        &est.correlation,
        &DiagnosticThresholds::default(),
        &|name| Some(format!("{name} not identifiable at steady state: {}", steady_advice(kind, name))),
        &|a, b| kind.pair_advice(a, b),
    );
    let rows = 2 * est.steady_samples;
    let sse: f64 = est.rms_residual.iter().map(|r| r * r * est.steady_samples as f64).sum();
    let fit = FitStatistics {
        outputs: vec!["ud".into(), "uq".into()],
        output_units: vec!["V".into(), "V".into()],
        fit_percent: est.fit_percent.to_vec(),
        rms_residual: est.rms_residual.to_vec(),
        loss: 0.5 * sse,
        mse: sse / rows as f64,
        aic: metrics::aic(sse, rows, n),
        bic: metrics::bic(sse, rows, n),
        fpe: metrics::fpe(sse, rows, n),
        whiteness: est.whiteness.clone(),
        samples: est.steady_samples,
        dof: rows.saturating_sub(n),
        counted: None,
        horizon: None,
    };
    let reason = if est.converged { Termination::StepTolerance } else { Termination::MaxIterations };
    let hc = est.control_period.map_or_else(
        || "continuous (no --control-period: see the note on the control period)".into(),
        |h| {
            format!(
                "at the drive's control period {h:e} s (exact periodic steady state of the stator-held step)"
            )
        },
    );
    FitResult {
        model: format!("{}_steady", kind.model_name()),
        experiments: experiments.iter().map(|e| e.name().to_string()).collect(),
        derived: derived_all(est, options),
        parameters,
        initial_states: Vec::new(),
        diagnostics,
        fit,
        correlation: est.correlation.clone(),
        correlation_names: labels,
        uncertainty: est.uncertainty.clone(),
        solver: SolverReport {
            name: "iv".into(),
            iterations: est.iterations as u64,
            termination: reason.to_string(),
            success: est.converged,
            reason,
            evaluations: est.iterations as u64 + 1,
            accepted_iterations: est.iterations as u64,
            trace: Vec::new(),
        },
        parameter_trace: Vec::new(),
        timing: Timing { read_s: 0.0, fit_s, total_s: fit_s },
        notes: std::iter::once(format!(
            "steady-state equations u_d = R_s i_d + L_d di_d/dt − ω_e L_q i_q, u_q = R_s i_q + L_q di_q/dt + ω_e L_d \
             i_d + √(2/3) ω_m K_e on the {} smooth samples of {} (each current's second differences at k − 1, k, \
             k + 1 within {}·√6 σ_i, or at k alone where a note says so; di/dt by central differences at the log's \
             rate), by instrumental variables (instruments: the mean and slope over the samples two away); equations \
             {hc}",
            est.steady_samples,
            est.samples,
            SteadyOptions::default().steady_sigmas
        ))
        .chain(est.notes.iter().filter(|n| n.contains("control period") || n.contains("smooth across")).cloned())
        .chain(widening)
        .collect(),
        warnings: Vec::new(),
    }
}

/// The derived quantities ([`derived`]: `k_t`, `psi_f`, the ratings) and, with a thermal
/// reference, the winding and magnet temperatures: one set per log when a parameter is
/// estimated per log, else one.
fn derived_all(est: &SteadyEstimate, options: &PmsmFitOptions) -> Vec<DerivedEstimate> {
    let kind = est.kind;
    // One set per log when a parameter is per log, else one shared set.
    let mut logs: Vec<Option<String>> = Vec::new();
    for e in est.experiment.iter().flatten() {
        if !logs.iter().flatten().any(|l| l == e) {
            logs.push(Some(e.clone()));
        }
    }
    if logs.is_empty() {
        logs.push(None);
    }
    let mut out = Vec::new();
    for log in logs {
        // The full vector's entry of each model parameter for this log.
        let at: Vec<usize> = kind
            .parameter_names()
            .iter()
            .filter_map(|n| {
                (0..est.names.len()).find(|&i| {
                    est.names[i] == *n && (est.experiment[i].is_none() || est.experiment[i] == log)
                })
            })
            .collect();
        if at.len() != kind.parameter_names().len() {
            continue;
        }
        let t: Vec<f64> = at.iter().map(|&i| est.theta[i]).collect();
        let s: Vec<f64> = at.iter().map(|&i| est.std_error[i]).collect();
        let corr = est.correlation[at[0]][at[at.len() - 1]];
        let with_log = |d: DerivedEstimate| DerivedEstimate { experiment: log.clone(), ..d };
        out.extend(derived(kind, options.pole_pairs, &t, &s, corr).into_iter().map(with_log));
        if let Some(th) = options.thermal {
            let psi = SQRT_2_3 / f64::from(options.pole_pairs);
            let k = t.len() - 1;
            out.extend(th.temperatures(t[0], s[0], psi * t[k], psi * s[k]).into_iter().map(with_log));
        }
    }
    out
}

/// The name the report gives the period term: the control period itself.
const PERIOD_SHOWN: &str = "h_c";

/// The control period `h_c = √h_c2` \[s\] as the report's nuisance parameter, from the
/// estimate `p` of `h_c2` \[s²\]: its interval the square roots of `h_c2`'s (clipped at
/// 0), its standard error by the delta method `se(h_c2)/(2 h_c)`, or `√se(h_c2)` when the
/// estimate is not positive (the period one standard error of `h_c2` amounts to).
fn control_period(p: ParameterEstimate) -> ParameterEstimate {
    let root = |v: f64| if v.is_nan() { v } else { v.max(0.0).sqrt() };
    let se = |s: f64| if p.value > 0.0 { s / (2.0 * p.value.sqrt()) } else { s.sqrt() };
    ParameterEstimate {
        name: PERIOD_SHOWN.into(),
        unit: "s".into(),
        value: root(p.value),
        std_error: se(p.std_error),
        std_error_white: se(p.std_error_white),
        ci95: p.ci95.map(root),
        nuisance: true,
        start: root(p.start),
        ..p
    }
}

/// `kind`'s steady-state model name, e.g. `spm-steady`, for messages.
pub(crate) fn flag(kind: MotorKind) -> String {
    format!("{}-steady", kind.model_name().trim_start_matches("pmsm_"))
}
