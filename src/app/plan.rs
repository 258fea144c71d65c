//! What a fit does to every log, decided from its [`FitRequest`] before any log is read
//! ([`Plan`]), and the fit of logs with it ([`fit_logs`]): used by the joint fit, the
//! batch ([`super::fit_each`]), the command line and the Python package.

use super::request::FitRequest;
use super::values::{Advance, DeadTime, Delay, InverterChoice, Method, Pll, PolePairs, Voltage};
use crate::estimate::{FitResult, PemOptions, SolverKind, Timing};
use crate::pmsm::ReportOptions;
use crate::pmsm::{
    CsvOptions, DqSource, Estimator, Frame, HoldChoice, InputSearch, InverterModel, MotorKind, PmsmFit,
    PmsmFitOptions, ThermalReference, VoltageInput, fit_estimating_input, fit_pmsm_by,
};
use std::time::Instant;

/// What a fit does to every log, decided from its request before any log is read: how to
/// read a log, how to report it, and the prediction-error fit (`None` for `--method ls`).
pub struct Plan {
    /// How a log is read.
    pub csv: CsvOptions,
    /// How the report states the log's scaling.
    pub report_options: ReportOptions,
    /// Surface or interior magnets.
    pub kind: MotorKind,
    /// The fit's options (pole pairs still 0: set per fit by [`fit_logs`]) and which input
    /// parameters are searched; `None` for `--method ls`.
    pub pem: Option<(PmsmFitOptions, InputSearch, Estimator)>,
}

/// The prediction-error fit of `logs` (jointly) with `options`: the pole pairs given or
/// chosen (`--pole-pairs auto`, with its note), the input search when `search` asks for
/// one, and the timing from `t0` with the `read_s` seconds it took to read the logs.
///
/// # Errors
/// Those of [`fit_pmsm`](crate::pmsm::fit_pmsm), [`fit_estimating_input`] and the pole-pair choice.
pub fn fit_logs(
    pole_pairs_arg: PolePairs,
    options: &PmsmFitOptions,
    search: InputSearch,
    estimator: Estimator,
    logs: &[crate::Experiment],
    t0: Instant,
    read_s: f64,
) -> crate::Result<PmsmFit> {
    let (n_p, auto_note) = pole_pairs(pole_pairs_arg, logs, options.model, Some(options))?;
    let options = PmsmFitOptions { pole_pairs: n_p, ..options.clone() };
    let fit = if search.delay || search.advance || search.speed_pll || search.dead_time_width {
        fit_estimating_input(logs, &options, search)?
    } else {
        fit_pmsm_by(logs, &options, estimator)?
    };
    let timing = Timing { read_s, total_s: t0.elapsed().as_secs_f64(), ..fit.report.timing.clone() };
    let pmsm_notes = fit.pmsm_notes.iter().cloned().chain(auto_note).collect();
    Ok(PmsmFit { report: FitResult { timing, ..fit.report }, pmsm_notes, ..fit })
}

/// The [`Plan`] of the request `a`, every combination the fit cannot honour refused.
///
/// # Errors
/// [`crate::Error::InvalidOption`] naming the flag: `--pole-pairs auto` with an
/// electrical speed or dq from phases, options `--method ls` cannot honour, input searches
/// with `--voltage actual`, `--r-s0`/`--psi-f0` without `--t0`, a dead-time mask without
/// the dead-time model, a dead-time model with the measured voltage; and those of
/// [`ThermalReference::try_new`] and the `--weighting` rule.
pub fn plan(a: &FitRequest) -> crate::Result<Plan> {
    let given = match a.pole_pairs {
        PolePairs::Given(n) => Some(n),
        PolePairs::Auto => None,
    };
    let steady_state = a.model.dynamics() == crate::pmsm::Dynamics::Steady;
    // The reader accepts slow telemetry's sample times whenever the model may be chosen
    // automatically: the fit decides between the dynamic and the steady-state equations
    // (and tells a fast log whose time column is in other units apart), not the reader.
    let csv = CsvOptions { pole_pairs: given, steady_state: true, ..a.reading.csv.clone() };
    if given.is_none() && (csv.speed_frame == Frame::Electrical || csv.source == DqSource::Phases) {
        return Err(crate::Error::InvalidOption {
            option: "pole-pairs".into(),
            reason:
                "auto cannot be used with an electrical speed or dq from phases, which need n_p to be read"
                    .into(),
        });
    }
    let report_options = ReportOptions { current_scale: csv.current_scale };
    let kind = a.model.kind();
    if steady_state {
        steady_only(a)?;
    }
    if let Method::Ls = a.method {
        ls_only(a)?;
        a.weighting.rule()?;
        return Ok(Plan { csv, report_options, kind, pem: None });
    }
    let speed_pll = match a.speed_pll {
        Some(Pll::Bandwidth(b)) => Some(b),
        _ => None,
    };
    let advance = match a.advance {
        Advance::Value(v) => v,
        Advance::Estimate => 1.5,
    };
    let input = match (a.voltage, a.delay) {
        (Voltage::Actual, _) => VoltageInput::Terminal,
        (Voltage::Reference, Delay::Samples(delay)) => VoltageInput::Reference { delay, advance, speed_pll },
        (Voltage::Reference, Delay::Estimate) => VoltageInput::Reference { delay: 1, advance, speed_pll },
    };
    let search = InputSearch {
        delay: matches!(a.delay, Delay::Estimate),
        advance: matches!(a.advance, Advance::Estimate),
        // A PWM fit estimates the controller's speed by default (it reads theta_m anyway):
        // the logged speed biases L by about 0.3 % where the controller advances its own.
        speed_pll: matches!(a.speed_pll, Some(Pll::Estimate))
            || (a.speed_pll.is_none()
                && matches!(a.voltage, Voltage::Reference)
                && matches!(a.pwm.inverter, InverterChoice::Pwm)),
        dead_time_width: matches!(a.dead_time_width, Some(Pll::Estimate)),
    };
    if matches!(a.voltage, Voltage::Actual)
        && (search.delay || search.advance || search.speed_pll || a.speed_pll.is_some())
    {
        return Err(crate::Error::InvalidOption {
            option: "voltage".into(),
            reason: "--delay estimate, --advance estimate and --speed-pll apply to --voltage reference"
                .into(),
        });
    }
    let thermal = match (a.t0, a.r_s0, a.psi_f0) {
        (None, None, None) => None,
        (Some(t0), r_s0, psi_f0) => Some(ThermalReference::try_new(t0, r_s0, psi_f0)?),
        (None, _, _) => {
            return Err(crate::Error::InvalidOption {
                option: "t0".into(),
                reason: "--r-s0 and --psi-f0 are values at a reference temperature: give it with --t0".into(),
            });
        }
    };
    let width = match a.dead_time_width {
        Some(Pll::Bandwidth(w)) => Some(w),
        _ => None,
    };
    let inverter = match a.dead_time {
        DeadTime::None => None,
        DeadTime::Estimate => Some(InverterModel { width, known: None, mask: a.dead_time_mask }),
        DeadTime::Volts(v) => Some(InverterModel { width, known: Some(v), mask: a.dead_time_mask }),
    };
    if inverter.is_none() && a.dead_time_mask.is_some() {
        return Err(crate::Error::InvalidOption {
            option: "dead-time-mask".into(),
            reason: "the mask belongs to the dead-time model: add --dead-time estimate (or a known voltage)"
                .into(),
        });
    }
    if inverter.is_some() && matches!(a.voltage, Voltage::Actual) {
        return Err(crate::Error::InvalidOption {
            option: "dead-time".into(),
            reason:
                "the measured terminal voltage already contains the inverter's error: use --voltage reference"
                    .into(),
        });
    }
    let pwm = a.pwm.inverter(a.u_dc)?;
    if pwm.is_some() && (inverter.is_some() || !matches!(a.voltage, Voltage::Reference)) {
        return Err(crate::Error::InvalidOption {
            option: "inverter".into(),
            reason:
                "--inverter pwm models the inverter between the voltage reference and the motor: it needs \
                     --voltage reference and replaces the averaged --dead-time model"
                    .into(),
        });
    }
    let options = PmsmFitOptions {
        // Set below: given, or chosen by fitting these options at each candidate.
        pole_pairs: 0,
        skip_setup_checks: false,
        force: a.reading.csv.force,
        input,
        inverter,
        // The PWM model applies the modulator's limit itself.
        voltage_limit: a.u_dc.filter(|_| pwm.is_none()).map(|u| u / 3f64.sqrt()),
        pwm,
        cable_resistance: a.cable_resistance,
        thermal,
        model: kind,
        dynamics: a.model.dynamics(),
        control_period: a.control_period,
        precision: a.precision.clone(),
        read_scales: [csv.current_scale, csv.voltage_scale],
        hold: a.hold,
        start: a.start.clone(),
        fixed: a.fix.iter().filter(|(_, v)| v.is_none()).map(|(n, _)| n.clone()).collect(),
        fixed_values: a.fix.iter().filter_map(|(n, v)| v.map(|v| (n.clone(), v))).collect(),
        bounds: a.bounds.clone(),
        pem: PemOptions {
            solver: a.solver,
            tolerances: a.tolerances,
            scaling: a.scaling,
            horizon: a.horizon,
            per_experiment: a.per_log.clone(),
            weighting: a.weighting.clone(),
            huber: a.huber,
            estimate_x0: !a.fixed_x0,
            prefilter: a.prefilter,
            output_weights: a.output_weights.clone(),
            progress: true,
            ..PemOptions::default()
        },
    };
    let estimator = match a.method {
        Method::Iv => Estimator::InstrumentalVariables,
        Method::Auto => Estimator::Auto,
        _ => Estimator::PredictionError,
    };
    if estimator == Estimator::InstrumentalVariables {
        crate::pmsm::check_iv_options(&options)?;
    }
    if estimator == Estimator::InstrumentalVariables
        && (search.delay || search.advance || search.speed_pll || search.dead_time_width)
    {
        return Err(crate::Error::InvalidOption {
            option: "method".into(),
            reason:
                "iv inverts the measured terminal voltage: it takes no input search (--delay, --advance, \
                     --speed-pll, --dead-time-width estimate)"
                    .into(),
        });
    }
    Ok(Plan { csv, report_options, kind, pem: Some((options, search, estimator)) })
}

/// The pole pairs given, or chosen by `--pole-pairs auto` with a note on how decisively:
/// the least-squares loss alone for `--method ls`, else the prediction-error loss of the
/// best least-squares candidates fitted with `options`.
pub fn pole_pairs(
    given: PolePairs,
    logs: &[crate::Experiment],
    kind: MotorKind,
    options: Option<&PmsmFitOptions>,
) -> crate::Result<(u32, Option<String>)> {
    use crate::pmsm::thresholds::POLE_PAIR_CANDIDATES as C;
    use crate::pmsm::{choose_pole_pairs, choose_pole_pairs_by_fit};
    match (given, options) {
        (PolePairs::Given(n), _) => Ok((n, None)),
        (PolePairs::Auto, None) => {
            let (n, ratio) = choose_pole_pairs(logs, kind, VoltageInput::Terminal)?;
            let note = format!(
                "pole pairs chosen automatically: {n} (least-squares loss of the voltage equations over {}-{}; the \
                 runner-up's is {ratio:.1} times higher)",
                C.start(),
                C.end()
            );
            Ok((n, Some(note)))
        }
        (PolePairs::Auto, Some(o)) => {
            let (n, ratio, fitted) = choose_pole_pairs_by_fit(logs, o)?;
            let list: Vec<String> = fitted.iter().map(|(n, l)| format!("{n}: {l:.6e}")).collect();
            let note = format!(
                "pole pairs chosen automatically: {n}, the lowest prediction-error loss of the best least-squares \
                 candidates over {}-{} ({}); the runner-up's is {ratio:.1} times higher",
                C.start(),
                C.end(),
                list.join(", ")
            );
            Ok((n, Some(note)))
        }
    }
}

/// Refuses the options that linear least squares cannot honour, naming them.
fn ls_only(a: &FitRequest) -> crate::Result<()> {
    let mut bad = Vec::new();
    let given = [
        ("--start", a.start.is_some()),
        ("--fix", !a.fix.is_empty()),
        ("--per-log", !a.per_log.is_empty()),
        ("--hold", !matches!(a.hold, HoldChoice::Auto)),
        ("--horizon", a.horizon.is_some()),
        ("--huber", a.huber.is_some()),
        ("--output-weights", a.output_weights.is_some()),
        ("--bounds", !a.bounds.is_empty()),
        ("--fixed-x0", a.fixed_x0),
        ("--solver", !matches!(a.solver, SolverKind::Auto)),
        ("--voltage reference", matches!(a.voltage, Voltage::Reference)),
        ("--cable-resistance", a.cable_resistance != 0.0),
        ("--dead-time", !matches!(a.dead_time, DeadTime::None)),
        ("--u-dc", a.u_dc.is_some()),
        ("--speed-pll", a.speed_pll.is_some()),
        ("--dead-time-width", a.dead_time_width.is_some()),
        ("--dead-time-mask", a.dead_time_mask.is_some()),
        ("--delay estimate", matches!(a.delay, Delay::Estimate)),
        ("--advance estimate", matches!(a.advance, Advance::Estimate)),
        ("--r-s0", a.r_s0.is_some()),
        ("--psi-f0", a.psi_f0.is_some()),
        ("--t0", a.t0.is_some()),
    ];
    for (flag, set) in given {
        if set {
            bad.push(flag);
        }
    }
    bad.extend(a.simulated_outputs.iter().map(String::as_str));
    if a.control_period.is_some() {
        bad.push("--control-period");
    }
    if a.precision.is_some() {
        bad.push("--precision");
    }
    if bad.is_empty() {
        Ok(())
    } else {
        Err(crate::Error::InvalidOption {
            option: "method".into(),
            reason: format!("--method ls cannot honour {}: drop them or use --method pem", bad.join(", ")),
        })
    }
}

/// Refuses the flags the steady-state equations (`--model spm-steady|ipm-steady`) cannot
/// honour, naming them; the fit's own options are checked by the library.
fn steady_only(a: &FitRequest) -> crate::Result<()> {
    let given =
        [("--method ls", matches!(a.method, Method::Ls)), ("--method iv", matches!(a.method, Method::Iv))];
    let bad: Vec<&str> = given
        .iter()
        .filter(|(_, set)| *set)
        .map(|(flag, _)| *flag)
        .chain(a.simulated_outputs.iter().map(String::as_str))
        .collect();
    if bad.is_empty() {
        return Ok(());
    }
    Err(crate::Error::InvalidOption {
        option: "model".into(),
        reason: format!(
            "the steady-state equations are fitted by instrumental variables and simulate no currents: they cannot \
             honour {}",
            bad.join(", ")
        ),
    })
}
