//! `greybox simulate`: a closed-loop drive log from a thesis scenario or a scenario file,
//! with its truth JSON beside it.

use super::output;
use crate::Error;
use crate::app::{Motor, SimulateRequest, drive_config};
use crate::data::Staged;
use crate::drive::{DriveLog, simulate_drive_with_progress};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
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
    let cfg = drive_config(&SimulateRequest::from(a))?;
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

impl From<&SimulateArgs> for SimulateRequest {
    /// The request of the flags (`--output` and `--print-config` are the command line's
    /// outputs, not the request's).
    fn from(a: &SimulateArgs) -> Self {
        SimulateRequest {
            scenario: a.scenario.clone(),
            config: a.config.clone(),
            motor: a.motor.into(),
            seed: a.seed,
            duration: a.duration,
            set: a.set.clone(),
            inverter: a.inverter,
            t_d: a.t_d,
            u_th: a.u_th,
            leg_state_width: a.leg_state_width,
            pwm_levels: a.pwm_levels,
        }
    }
}

impl From<MotorArg> for Motor {
    fn from(m: MotorArg) -> Self {
        match m {
            MotorArg::Spm => Motor::Spm,
            MotorArg::Ipm => Motor::Ipm,
            MotorArg::IpmSat => Motor::IpmSat,
        }
    }
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
