//! `greybox mechanics`: inertia, viscous and Coulomb friction, gravity and a constant load
//! from the speed and angle of drive logs, driven by the torque of the electrical model
//! fitted to the same logs (or of a given `K_t`), with the friction per log for a trend
//! (issue 33).

use super::columns::ColumnArgs;
use super::output;
use crate::data::{ColumnMap, CsvSpec, Experiment, TimeWindow, read_csv};
use crate::estimate::FitResult;
use crate::pmsm::{
    Axis, LOAD_TORQUE, MechanicsFit, MechanicsOptions, MechanicsTerms, MotorParameters, PmsmFitOptions,
    SQRT_2_3, fit_mechanics, fit_pmsm,
};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;

/// Arguments of `greybox mechanics`.
#[derive(Args, Debug)]
#[command(
    after_help = "The logs are read as by `greybox fit`; without --k-t the electrical model is fitted to them \
first (jointly) and its torque 1.5 n_p (ψ_f i_q + (L_d − L_q) i_d i_q) drives the shaft. A load-torque column \
(--col-load) is subtracted when every log has it. The intervals take the torque model as exact. A linear axis \
(--lead for a screw or rack, --pole-pitch for a linear motor) is reported in kg, N s/m and N. See \
docs/mechanics.md."
)]
#[command(group = clap::ArgGroup::new("linear").args(["lead", "pole_pitch"]).multiple(false))]
pub struct MechanicsArgs {
    /// Drive logs (CSV, plain or gzip; Parquet, Arrow IPC), fitted jointly.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Number of pole pairs n_p of the motor.
    #[arg(long, short = 'p')]
    pub pole_pairs: u32,
    /// A known torque constant K_t [N m/A, peak dq current] instead of the electrical fit:
    /// then only the time, iq, the speed (and the angle with --gravity) are read.
    #[arg(long, value_name = "N m/A", conflicts_with = "k_f")]
    pub k_t: Option<f64>,
    /// A linear axis driven through a screw, rack or belt: M metres of travel per motor
    /// revolution (a ball screw's lead over the gear ratio); the logs are the motor's, the
    /// report in kg, N s/m and N.
    #[arg(long, value_name = "M", conflicts_with = "pole_pitch")]
    pub lead: Option<f64>,
    /// A linear motor of pole pitch M [m] whose speed and position columns are in m/s and m
    /// (read as a shaft of lead 2 n_p M); the report in kg, N s/m and N.
    #[arg(long, value_name = "M")]
    pub pole_pitch: Option<f64>,
    /// A known force constant K_f [N/A, peak dq current] of a linear axis (--lead or
    /// --pole-pitch) instead of the electrical fit, read as --k-t is.
    #[arg(long, value_name = "N/A", requires = "linear")]
    pub k_f: Option<f64>,
    /// A gravity load m g l sin θ_m (angle 0 hanging down).
    #[arg(long)]
    pub gravity: bool,
    /// A constant load torque t_0.
    #[arg(long)]
    pub constant_load: bool,
    /// Viscous and Coulomb friction per log (inertia and loads shared): the friction trend.
    #[arg(long)]
    pub per_log: bool,
    /// Window length [s].
    #[arg(long, default_value_t = 0.01, value_name = "S")]
    pub window: f64,
    /// Speed [rad/s; m/s on a linear axis] over which the Coulomb friction changes sign, or
    /// `estimate` (the lowest loss between 1e-4 and 1 times the logs' peak speed).
    #[arg(long, default_value = "estimate", value_name = "SPEED|estimate", value_parser = |s: &str| super::args::Pll::positive_or_estimate(s, "a positive speed in rad/s"))]
    pub coulomb_speed: super::args::Pll,
    /// Column of a load torque [N m] (on a linear axis a force [N]), used when every log has it.
    #[arg(long, default_value = LOAD_TORQUE, value_name = "NAME")]
    pub col_load: String,
    /// The report's outputs.
    #[command(flatten)]
    pub report: output::ReportArgs,
    /// Log columns and units (as `greybox fit`).
    #[command(flatten)]
    pub columns: ColumnArgs,
}

/// The joint electrical and mechanical report.
#[derive(Serialize)]
struct Joint<'a> {
    /// The electrical fit that gave the torque model (none with `--k-t`).
    electrical: Option<&'a FitResult>,
    /// The torque model.
    motor: MotorParameters,
    /// The mechanical fit.
    mechanics: &'a MechanicsFit,
}

/// Runs `greybox mechanics`; whether both fits are trusted.
///
/// # Errors
/// Unreadable logs, a bad `--k-t`, window or ω_c, a failed fit, an output that cannot be
/// written (nothing is written then).
pub fn run_mechanics(a: &MechanicsArgs) -> crate::Result<bool> {
    a.report.run(&a.logs, "fit", || mechanics_outcome(a))
}

/// The fits of `greybox mechanics` and their joint report, nothing printed or written.
///
/// # Errors
/// As [`run_mechanics`] but for the output.
pub fn mechanics_outcome(a: &MechanicsArgs) -> crate::Result<output::Outcome> {
    let extra = (a.col_load.as_str(), LOAD_TORQUE, "N m");
    let axis = axis(a)?;
    let terms = MechanicsTerms { gravity: a.gravity, constant: a.constant_load };
    // The axis' faults before the electrical fit spends its time.
    axis.check(terms)?;
    let k_t = a.k_t.or(a.k_f.map(|k_f| k_f / axis.radians_per_unit()));
    let logs: Vec<Experiment> = match k_t {
        Some(_) => read_mechanical_logs(a)?,
        None => a.columns.read_logs_with_channel(&a.logs, a.pole_pairs, extra)?,
    };
    let logs = match a.pole_pitch {
        Some(_) => logs.into_iter().map(|e| linear_motor_log(e, axis)).collect::<crate::Result<_>>()?,
        None => logs,
    };
    // The angle a gravity term needs, before the electrical fit spends its time.
    for e in logs.iter().filter(|_| a.gravity) {
        e.channel("theta_m")?;
    }
    let n_p = a.pole_pairs;
    let (electrical, motor) = match k_t {
        Some(k_t) if k_t.is_finite() && k_t != 0.0 => {
            (None, MotorParameters { r_s: 0.0, l_d: 0.0, l_q: 0.0, psi_f: k_t / (1.5 * f64::from(n_p)), n_p })
        }
        Some(k_t) => {
            let (flag, what) = if a.k_f.is_some() { ("--k-f", "K_f") } else { ("--k-t", "K_t") };
            let given = a.k_f.unwrap_or(k_t);
            return Err(crate::Error::InvalidOption {
                option: flag.into(),
                reason: format!("{given}: {what} must be finite and non-zero"),
            });
        }
        None => {
            let fit = fit_pmsm(&logs, &PmsmFitOptions::new(n_p))?.report;
            let motor = motor_of(&fit, n_p);
            (Some(fit), motor)
        }
    };
    // K_t's relative standard error from the electrical fit (0 for a given K_t).
    let k_t_relative_se = electrical
        .as_ref()
        .and_then(|e| e.derived("k_t"))
        .map_or(0.0, |k| if k.std_error.is_finite() { (k.std_error / k.value).abs() } else { 0.0 });
    let options = MechanicsOptions {
        k_t_relative_se,
        window: a.window,
        coulomb_speed: match a.coulomb_speed {
            super::args::Pll::Bandwidth(w_c) => Some(w_c),
            _ => None,
        },
        terms,
        per_log_friction: a.per_log,
        axis,
        ..MechanicsOptions::new(motor)
    };
    let mechanics = fit_mechanics(&logs, &options)?;
    let mut text = String::new();
    if let Some(e) = &electrical {
        text += &format!("Electrical fit (the torque model):\n{}\n", crate::pmsm::estimate_table(e));
    }
    text += &mechanics.to_string();
    let mut untrusted: Vec<String> = electrical
        .as_ref()
        .map(|e| e.untrusted_codes().into_iter().map(|c| format!("electrical {c}")).collect())
        .unwrap_or_default();
    untrusted.extend(mechanics.fit.untrusted_codes().into_iter().map(|c| format!("mechanics {c}")));
    let joint = Joint { electrical: electrical.as_ref(), motor, mechanics: &mechanics };
    Ok(output::Outcome::new(text, &joint, untrusted))
}

/// The axis of `--lead` or `--pole-pitch` (a linear motor: lead `2 n_p τ_p`), or the shaft.
///
/// # Errors
/// [`crate::Error::InvalidOption`] naming the flag for a length that is not positive and
/// finite, and `--pole-pitch` with a speed or angle unit or frame flag (its columns are in
/// m/s and m).
fn axis(a: &MechanicsArgs) -> crate::Result<Axis> {
    let positive = |flag: &str, x: f64| {
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(crate::Error::InvalidOption {
                option: flag.into(),
                reason: format!("{x} m: a length must be positive and finite"),
            })
        }
    };
    if let Some(tau_p) = a.pole_pitch {
        if a.columns.dq_from_phases {
            return Err(crate::Error::InvalidOption {
                option: "--pole-pitch".into(),
                reason:
                    "not with --dq-from-phases: the Park transform would take the position in metres for an \
                         angle; give the dq columns"
                        .into(),
            });
        }
        let o = a.columns.options();
        if o.speed_factor(a.pole_pairs) != 1.0 || o.angle_factor(a.pole_pairs) != 1.0 {
            return Err(crate::Error::InvalidOption {
                option: "--pole-pitch".into(),
                reason:
                    "a linear motor's speed and position columns are read in m/s and m: drop --speed-unit, \
                         --angle-unit, --speed-frame and --negate-speed"
                        .into(),
            });
        }
        return Ok(Axis::Linear { lead: 2.0 * f64::from(a.pole_pairs) * positive("--pole-pitch", tau_p)? });
    }
    Ok(a.lead.map(|l| positive("--lead", l)).transpose()?.map_or(Axis::Rotary, |lead| Axis::Linear { lead }))
}

/// A linear motor's log `e` (speed `w_m` in m/s, position `theta_m` in m) as the shaft of
/// `axis`: both times `2π/lead` \[rad/m\].
///
/// # Errors
/// Those of [`Experiment::with_channel`].
fn linear_motor_log(e: Experiment, axis: Axis) -> crate::Result<Experiment> {
    let r = axis.radians_per_unit();
    let mut e = e;
    for (name, unit) in [("w_m", "rad/s"), ("theta_m", "rad")] {
        if let Some(c) = e.get(name) {
            let values = c.values.iter().map(|v| v * r).collect();
            e = e.with_channel(crate::data::Channel::new(name, unit, values))?;
        }
    }
    Ok(e)
}

/// The logs of `--k-t`, which needs no electrical fit: only the time, `iq`, the speed, the
/// angle with `--gravity` and the load column where present are read (the voltages and `id`
/// may be absent), with the units, frames and scales of `greybox fit`'s flags, and
/// `--from`/`--to` keep their rows.
///
/// # Errors
/// [`crate::Error::InvalidOption`] for `--dq-from-phases` or `--split-gaps`, which need the
/// electrical reader, and for a window that keeps fewer than 2 rows; those of
/// [`read_csv`] (a missing column named with its flag).
fn read_mechanical_logs(a: &MechanicsArgs) -> crate::Result<Vec<Experiment>> {
    let c = &a.columns;
    for (flag, set) in [("--dq-from-phases", c.dq_from_phases), ("--split-gaps", c.split_gaps)] {
        if set {
            return Err(crate::Error::InvalidOption {
                option: flag.into(),
                reason: "not with --k-t, which reads iq and the speed only: give the dq current column"
                    .into(),
            });
        }
    }
    let o = c.options();
    let n_p = a.pole_pairs;
    let column = |col: &str, channel: &str, unit: &str, scale: f64, required: bool| ColumnMap {
        scale,
        required,
        ..ColumnMap::new(col, channel, unit)
    };
    let spec = CsvSpec {
        time: c.col_t.clone(),
        time_scale: 1.0 / o.time_unit.per_second(),
        columns: vec![
            column(&c.col_iq, "iq", "A", o.current_scale.factor(), true),
            column(&c.col_w, "w_m", "rad/s", o.speed_factor(n_p), true),
            column(&c.col_theta, "theta_m", "rad", o.angle_factor(n_p), a.gravity),
            column(&a.col_load, LOAD_TORQUE, "N m", 1.0, false),
        ],
        limits: o.limits,
        delimiter: o.delimiter,
    };
    let flag = |col: &str| match col {
        x if x == c.col_iq => "--col-iq",
        x if x == c.col_w => "--col-w",
        x if x == c.col_theta => "--col-theta",
        x if x == c.col_t => "--col-t",
        _ => "--col-load",
    };
    a.logs
        .iter()
        .map(|path| {
            let e = read_csv(path, &spec).map_err(|e| match e {
                crate::Error::MissingColumn { path, column, available } => crate::Error::InvalidOption {
                    option: flag(&column).into(),
                    reason: format!("{}: no column `{column}` (header: {available})", path.display()),
                },
                e => e,
            })?;
            windowed(e, &o.window)
        })
        .collect()
}

/// The rows of `e` whose times `t0 + k h` \[s\] the window keeps (`from ≤ t ≤ to`, both
/// optional: [`TimeWindow::contains`]).
///
/// # Errors
/// [`crate::Error::InvalidOption`] (`--from/--to`) when fewer than 2 rows are kept.
fn windowed(e: Experiment, window: &TimeWindow) -> crate::Result<Experiment> {
    if window.from.is_none() && window.to.is_none() {
        return Ok(e);
    }
    let kept = |k: &usize| window.contains(e.t0() + *k as f64 * e.h());
    let first = (0..e.len()).find(kept).unwrap_or(e.len());
    let end = (first..e.len()).take_while(kept).last().map_or(first, |k| k + 1);
    if end < first + 2 {
        return Err(crate::Error::InvalidOption {
            option: "--from/--to".into(),
            reason: format!("{}: the window keeps {} rows; it needs at least 2", e.name(), end - first),
        });
    }
    e.slice(first..end)
}

/// The torque model of an electrical fit: `ψ_f = K_e √(2/3) / n_p` (MODEL.md §1), the
/// inductances `l_d, l_q` (or `l_s` for both).
fn motor_of(fit: &FitResult, n_p: u32) -> MotorParameters {
    let value = |name: &str| fit.parameter(name).map(|p| p.value);
    let l_s = value("l_s").unwrap_or(0.0);
    MotorParameters {
        r_s: value("r_s").unwrap_or(0.0),
        l_d: value("l_d").unwrap_or(l_s),
        l_q: value("l_q").unwrap_or(l_s),
        psi_f: value("k_e").unwrap_or(f64::NAN) * SQRT_2_3 / f64::from(n_p),
        n_p,
    }
}
