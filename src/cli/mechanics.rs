//! `greybox mechanics`: inertia, viscous and Coulomb friction, gravity and a constant load
//! from the speed and angle of drive logs, driven by the torque of the electrical model
//! fitted to the same logs (or of a given `K_t`), with the friction per log for a trend
//! (issue 33).

use super::columns::ColumnArgs;
use super::output;
use crate::data::{ColumnMap, CsvSpec, Experiment, TimeWindow, read_csv};
use crate::estimate::FitResult;
use crate::pmsm::{
    LOAD_TORQUE, MechanicsFit, MechanicsOptions, MechanicsTerms, MotorParameters, PmsmFitOptions, SQRT_2_3,
    fit_mechanics, fit_pmsm,
};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;

/// Arguments of `greybox mechanics`.
#[derive(Args, Debug)]
#[command(
    after_help = "The logs are read as by `greybox fit`; without --k-t the electrical model is fitted to them \
first (jointly) and its torque 1.5 n_p (ψ_f i_q + (L_d − L_q) i_d i_q) drives the shaft. A load-torque column \
(--col-load) is subtracted when every log has it. The intervals take the torque model as exact. See \
docs/mechanics.md."
)]
pub struct MechanicsArgs {
    /// Drive logs (CSV, plain or gzip; Parquet, Arrow IPC), fitted jointly.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Number of pole pairs n_p of the motor.
    #[arg(long, short = 'p')]
    pub pole_pairs: u32,
    /// A known torque constant K_t [N m/A, peak dq current] instead of the electrical fit:
    /// then only the time, iq, the speed (and the angle with --gravity) are read.
    #[arg(long, value_name = "N m/A")]
    pub k_t: Option<f64>,
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
    /// Speed [rad/s] over which the Coulomb friction changes sign, or `estimate` (the lowest
    /// loss between 1e-4 and 1 times the logs' peak speed).
    #[arg(long, default_value = "estimate", value_name = "RAD/S|estimate", value_parser = super::args::parse_speed)]
    pub coulomb_speed: super::args::Pll,
    /// Column of a load torque [N m], used when every log has it.
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
    let logs: Vec<Experiment> = match a.k_t {
        Some(_) => read_mechanical_logs(a)?,
        None => a.columns.read_logs_with_channel(&a.logs, a.pole_pairs, extra)?,
    };
    // The angle a gravity term needs, before the electrical fit spends its time.
    for e in logs.iter().filter(|_| a.gravity) {
        e.channel("theta_m")?;
    }
    let n_p = a.pole_pairs;
    let (electrical, motor) = match a.k_t {
        Some(k_t) if k_t.is_finite() && k_t != 0.0 => {
            (None, MotorParameters { r_s: 0.0, l_d: 0.0, l_q: 0.0, psi_f: k_t / (1.5 * f64::from(n_p)), n_p })
        }
        Some(k_t) => {
            return Err(crate::Error::InvalidOption {
                option: "--k-t".into(),
                reason: format!("{k_t}: K_t must be finite and non-zero"),
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
        terms: MechanicsTerms { gravity: a.gravity, constant: a.constant_load },
        per_log_friction: a.per_log,
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
