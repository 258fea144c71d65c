//! `greybox simulate`: a closed-loop drive log from a thesis scenario or a scenario file,
//! with its truth JSON beside it.

use super::output;
use crate::Error;
use crate::data::Staged;
use crate::drive::{
    DriveConfig, DriveLog, IPM_MOTOR, IPM_SATURATION, SATURATED_IPM_MOTOR, SCENARIOS, SPM_MOTOR, scenario,
    simulate_drive_with_progress,
};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::Value;
use std::io::IsTerminal;
use std::io::Write as _;
use std::path::PathBuf;

/// Arguments of `greybox simulate`.
#[derive(Args, Debug)]
#[command(after_help = "Scenarios (thesis ch. 5-6): exp1 MRAS validation (torque step, K_t and R_s ramps), \
exp2 position step with K_t 20 % too high in the controller, exp3 back-and-forth moves at increasing speeds, \
exp4 exp3 on a warm motor, exp5 low acceleration, exp6 material-handling cycle with d-current injections. \
Write one out with --print-config to start your own, and run it with --config.")]
pub struct SimulateArgs {
    /// A thesis scenario (exp1 … exp6) or a commissioning one (standstill: a locked-rotor test).
    #[arg(long, required_unless_present = "config", conflicts_with = "config")]
    pub scenario: Option<String>,
    /// A scenario file (JSON, as --print-config writes it); missing fields take the defaults.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The log to write (CSV; gzip when it ends in .gz; Parquet for .parquet, Arrow IPC for
    /// .arrow/.feather); the truth goes to the same name with .truth.json.
    #[arg(long, short = 'o', required_unless_present = "print_config")]
    pub output: Option<PathBuf>,
    /// The motor of a --scenario: a small surface-magnet servo or an interior-magnet motor.
    #[arg(long, value_enum, default_value_t = MotorArg::Spm)]
    pub motor: MotorArg,
    /// Seed of the sensor noise (the same seed gives the same log, bit for bit).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Length of the record [s].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Set any field of the scenario, by its path in the scenario file: `motor.r_s=1.1`,
    /// `inverter.v_dt=9.2`, `sensors.current_noise=0.05`, `control.h=1.25e-4` (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// The inverter: the averaged one (none: its `inverter.v_dt` error, 0 by default) or
    /// pwm, switching-resolved (carrier at 1/(2h), min-max modulation, the DC link
    /// `control.u_dc`) with --t-d, --u-th, --leg-state-width, --pwm-levels.
    #[arg(long, value_enum, default_value_t = crate::app::InverterChoice::None)]
    pub inverter: crate::app::InverterChoice,
    /// Dead time t_d of --inverter pwm [s].
    #[arg(long, default_value_t = 2e-6)]
    pub t_d: f64,
    /// Device threshold voltage u_th of --inverter pwm [V].
    #[arg(long, default_value_t = 1.0)]
    pub u_th: f64,
    /// Width i_w of the smooth leg state (2/π)·atan(i/i_w) of --inverter pwm [A]; 0: the sign.
    #[arg(long, default_value_t = 0.0)]
    pub leg_state_width: f64,
    /// Levels of the PWM counter of --inverter pwm; 0: continuous duty ratios.
    #[arg(long, default_value_t = 0)]
    pub pwm_levels: u32,
    /// Print the scenario (after --set, --seed, --duration) as JSON to stdout and stop.
    #[arg(long)]
    pub print_config: bool,
}

/// The motor of a thesis scenario (`--motor`): `spm` (a small surface-magnet servo),
/// `ipm` (an interior-magnet motor) or `ipm-sat` (a saturating interior-magnet motor,
/// [`crate::drive::IPM_SATURATION`]).
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MotorArg {
    Spm,
    Ipm,
    IpmSat,
}

/// Runs `greybox simulate`.
///
/// # Errors
/// An unknown scenario or field, an unreadable or invalid scenario file, a value of the
/// wrong type, a configuration [`DriveConfig::validate`] refuses, a diverging simulation,
/// an output that cannot be written (nothing is written then).
pub fn run_simulate(a: &SimulateArgs) -> crate::Result<()> {
    let cfg = config(a)?;
    if a.print_config {
        // A closed pipe (`| head`) ends the output, not the program.
        let text = serde_json::to_string_pretty(&cfg).unwrap_or_default();
        let _ = writeln!(std::io::stdout(), "{text}");
        return Ok(());
    }
    let Some(path) = &a.output else {
        return Err(Error::InvalidOption { option: "output".into(), reason: "give -o LOG.csv".into() });
    };
    let inputs: Vec<PathBuf> = a.config.iter().cloned().collect();
    let truth = DriveLog::truth_path(path);
    output::check_all(&[("--output", Some(path.as_path())), ("--output", Some(truth.as_path()))], &inputs)?;
    let bar = progress();
    let log = simulate_drive_with_progress(&cfg, &mut |k, n| {
        bar.set_length(n as u64);
        bar.set_position(k as u64);
    });
    bar.finish_and_clear();
    let log = log?;
    let mut staged = Staged::new();
    log.stage(&mut staged, path)?;
    let t = &log.truth;
    super::output::stdout(
        &(format!(
            "{}: {} samples at h = {} s ({} s) -> {} and {}; plant at start r_s {} ohm, l_d {} H, l_q {} H, psi_f {} V s, \
         n_p {}, k_e {:.6} V s/rad{}",
            t.scenario,
            t.samples,
            t.h,
            cfg.duration,
            path.display(),
            DriveLog::truth_path(path).display(),
            t.start.r_s,
            t.start.l_d,
            t.start.l_q,
            t.start.psi_f,
            t.start.n_p,
            t.k_e,
            if t.time_varying { " (parameters change within the record: see the truth file)" } else { "" }
        ) + "\n"),
    )?;
    staged.commit()
}

/// The scenario of `greybox simulate`'s flags: the thesis scenario or the scenario file,
/// with `--seed`, `--duration` and every `--set` applied, validated.
///
/// # Errors
/// An unknown scenario or field, an unreadable or invalid scenario file, a value of the
/// wrong type, a configuration [`DriveConfig::validate`] refuses.
pub fn config(a: &SimulateArgs) -> crate::Result<DriveConfig> {
    let mut cfg = match (&a.scenario, &a.config) {
        (Some(name), _) => {
            let motor = match a.motor {
                MotorArg::Spm => SPM_MOTOR,
                MotorArg::Ipm => IPM_MOTOR,
                MotorArg::IpmSat => SATURATED_IPM_MOTOR,
            };
            let saturation = matches!(a.motor, MotorArg::IpmSat).then_some(IPM_SATURATION);
            DriveConfig { saturation, ..scenario(name, motor)? }
        }
        (None, Some(path)) => {
            let text =
                std::fs::read_to_string(path).map_err(|source| Error::Io { path: path.clone(), source })?;
            serde_json::from_str::<DriveConfig>(&text).map_err(|e| Error::InvalidOption {
                option: "config".into(),
                reason: format!("{}: {e}", path.display()),
            })?
        }
        (None, None) => {
            return Err(Error::InvalidOption {
                option: "scenario".into(),
                reason: format!(
                    "give --scenario ({}, {}) or --config FILE",
                    SCENARIOS.join(", "),
                    crate::drive::COMMISSIONING.join(", ")
                ),
            });
        }
    };
    if a.inverter == crate::app::InverterChoice::Pwm {
        cfg.inverter.pwm = Some(crate::drive::PwmPlant {
            t_d: a.t_d,
            u_th: a.u_th,
            i_w: a.leg_state_width,
            levels: a.pwm_levels,
        });
    }
    if let Some(seed) = a.seed {
        cfg.seed = seed;
    }
    if let Some(d) = a.duration {
        cfg.duration = d;
    }
    for s in &a.set {
        cfg = set_field(&cfg, s)?;
    }
    cfg.validate()?;
    Ok(cfg)
}

/// The configuration with the field at the dotted `path` set to `value` (`PATH=VALUE`,
/// the value as JSON, e.g. a number, `null` or `[[0, 1], [2, 3]]`).
///
/// # Errors
/// [`Error::InvalidOption`] (`set`) for text without `=`, a value that is not JSON, a path
/// that is not a field (naming the fields there), a value of the wrong type.
pub fn set_field(cfg: &DriveConfig, assignment: &str) -> crate::Result<DriveConfig> {
    let bad = |reason: String| Error::InvalidOption { option: "set".into(), reason };
    let (path, value) =
        assignment.split_once('=').ok_or_else(|| bad(format!("`{assignment}`: expected PATH=VALUE")))?;
    let value: Value = serde_json::from_str(value.trim())
        .map_err(|e| bad(format!("`{assignment}`: the value is not JSON: {e}")))?;
    let mut root = serde_json::to_value(cfg).map_err(|e| bad(e.to_string()))?;
    let pointer = format!("/{}", path.trim().replace('.', "/"));
    let Some(slot) = root.pointer_mut(&pointer) else {
        // Name the fields where the path stops matching: the deepest object along it.
        let parts: Vec<&str> = path.trim().split('.').collect();
        let mut at = &serde_json::to_value(cfg).map_err(|e| bad(e.to_string()))?;
        let mut prefix = Vec::new();
        for part in &parts {
            match at.get(part) {
                Some(next) if next.is_object() => {
                    at = next;
                    prefix.push(*part);
                }
                _ => break,
            }
        }
        let fields: Vec<String> = at
            .as_object()
            .map(|o| {
                o.keys()
                    .map(|k| prefix.iter().chain([&k.as_str()]).copied().collect::<Vec<_>>().join("."))
                    .collect()
            })
            .unwrap_or_default();
        return Err(bad(format!(
            "`{path}` is not a field of the scenario; the fields there are: {} (all of them: --print-config)",
            fields.join(", ")
        )));
    };
    *slot = value;
    serde_json::from_value(root).map_err(|e| bad(format!("`{assignment}`: {e}")))
}

/// A bar of the simulated samples on stderr when it is a terminal (hidden otherwise).
fn progress() -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(0);
    if let Ok(style) = ProgressStyle::with_template(
        "simulating {pos}/{len} samples [{bar:30}] {elapsed_precise} (eta {eta})",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}
