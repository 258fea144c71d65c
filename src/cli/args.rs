//! Command-line arguments of `greybox fit` and their mapping to library options.

use crate::app::values::{parse_bounds, parse_fix, parse_mask, parse_precision, parse_weighting};
use crate::app::{FitRequest, PwmRequest};
use crate::estimate::{PrecisionTarget, ScalingKind, SolverKind, Tolerances, WeightingKind};
use crate::pmsm::HoldChoice;
use clap::Args;
use std::path::PathBuf;

pub use super::columns::ColumnArgs;
pub use super::values::FormatArg;
pub use crate::app::{Advance, DeadTime, Delay, Method, ModelChoice, Pll, PolePairs, Voltage};

/// The flags of `greybox fit` (and of `fit --each`), as parsed; converted into the
/// application layer's [`FitRequest`] (`FitRequest::from(&args)`), which
/// [`crate::app::plan`] turns into library options.
#[derive(Args, Debug)]
pub struct FitArgs {
    /// Exit with 0 even when the fit did not converge or a warning makes it untrusted (the
    /// default exit code is then 3; the report is written either way).
    #[arg(help_heading = "Output", long)]
    pub allow_unconverged: bool,
    /// Drive logs (CSV, plain or gzip; Parquet, Arrow IPC). Several logs are fitted jointly
    /// with shared parameters.
    #[arg(required_unless_present = "each")]
    pub logs: Vec<PathBuf>,
    // Batch fits (issue 17 item 2): `cli::batch`.
    /// Fit every log of a folder (its .csv, .csv.gz, .parquet, .pq, .arrow, .arrows,
    /// .feather, .ipc files) or every file a glob matches (`'runs/*.csv.gz'`, quoted), each
    /// on its own, in parallel, in file-name order; a log that cannot be read or fitted is
    /// reported and skipped. Exit code 4 when any log failed.
    #[arg(help_heading = "Batch (--each)", long, value_name = "DIR_OR_GLOB", conflicts_with_all = ["logs", "per_log", "json", "plot", "residuals", "format"])]
    pub each: Option<String>,
    /// With --each: write the summary (one row per log: status, parameters with standard
    /// errors and 95 % intervals, derived quantities, fit %, hold, warnings) to PATH.csv and
    /// PATH.json (an extension .csv or .json given is dropped first).
    #[arg(help_heading = "Batch (--each)", long, value_name = "PATH")]
    pub summary: Option<PathBuf>,
    /// With --each: write the trend plot (SVG) of every parameter over the logs, in file
    /// order, with 95 % intervals.
    #[arg(help_heading = "Batch (--each)", long, value_name = "PATH.svg")]
    pub trend: Option<PathBuf>,
    /// Number of pole pairs n_p of the motor, or `auto` (the lowest least-squares loss of
    /// the voltage equations over 1-32 pole pairs; the report gives the runner-up's ratio).
    #[arg(help_heading = "Motor and model", long, short = 'p', value_parser = by_str::<PolePairs>)]
    pub pole_pairs: PolePairs,
    /// Machine model: surface (spm: r_s, l_s, k_e) or interior magnets (ipm: r_s, l_d, l_q, k_e),
    /// dynamic unless the sample time is too long for it (then the steady-state equations,
    /// with a note); spm-steady, ipm-steady: the steady-state equations of slow telemetry
    /// (1-100 Hz; sample times up to 10 s).
    #[arg(help_heading = "Motor and model", long, value_enum, default_value_t = ModelChoice::Spm)]
    pub model: ModelChoice,
    /// The drive's control (PWM) period [s] for the steady-state equations: point-sampled
    /// currents are related to the period-mean voltage exactly (without it the back-EMF
    /// reads low by up to (w_e h_c)^2/12).
    #[arg(help_heading = "Motor and model", long, value_name = "SECONDS")]
    pub control_period: Option<f64>,
    /// The accuracy a fit must reach to exit 0, each parameter to X % at three standard
    /// errors: off (none), or NAME=X%[,NAME=X%...] (a value without % is a fraction).
    /// Default: r_s=0.5%,k_e=0.05% for the steady-state equations (1.3 K of winding, 0.45 K
    /// of magnet temperature), none for the dynamic model.
    #[arg(help_heading = "Motor and model", long, value_name = "off|NAME=X%,...", value_parser = parse_precision)]
    // The full path keeps clap from reading `Vec` as a flag given several times.
    pub precision: Option<::std::vec::Vec<PrecisionTarget>>,
    /// Voltage hold between samples: auto picks the one with the lower loss.
    #[arg(help_heading = "Motor and model", long, value_parser = super::values::listed::<HoldChoice>(), default_value = "auto")]
    pub hold: HoldChoice,
    /// Voltage that drives the model: the measured terminal voltage (actual: columns ud, uq)
    /// or the controller's reference (reference: ud_ref, uq_ref, applied --delay samples later
    /// with an angle advance of --advance ω_e h, stator hold).
    #[arg(help_heading = "Voltage input", long, value_enum, default_value_t = Voltage::Actual)]
    pub voltage: Voltage,
    /// Computational delay of the reference [samples], or `estimate` (integer search 0–3 by
    /// the lowest loss).
    #[arg(help_heading = "Voltage input", long, default_value = "1", value_parser = by_str::<Delay>)]
    pub delay: Delay,
    /// Modulator angle advance of the reference, in units of ω_e h, or `estimate`
    /// (golden-section search in [-1, 4] by the lowest loss, after the delay).
    #[arg(help_heading = "Voltage input", long, default_value = "1.5", value_parser = by_str::<Advance>)]
    pub advance: Advance,
    /// The controller advances the reference with a speed estimated from theta_m by a
    /// phase-locked loop of this bandwidth [rad/s], `estimate` (search by the lowest loss) or
    /// `logged` (the logged speed); default: `logged`, `estimate` with --inverter pwm.
    #[arg(help_heading = "Voltage input", long, value_parser = by_str::<Pll>)]
    pub speed_pll: Option<Pll>,
    /// The inverter's dead-time and device-drop voltage as a nuisance parameter v_dt (per
    /// phase −v_dt·sign(i_x); needs theta_m and --voltage reference): `none`, `estimate`, or
    /// a known value in volts.
    #[arg(help_heading = "Inverter and cable", long, default_value = "none", value_parser = by_str::<DeadTime>)]
    pub dead_time: DeadTime,
    /// Width of the smooth sign of the dead-time model [A] (default 2 % of the peak current),
    /// or `estimate` (search by the lowest loss).
    #[arg(help_heading = "Inverter and cable", long, value_parser = Pll::width)]
    pub dead_time_width: Option<Pll>,
    /// Weight out the periods in which a phase current comes within this many amperes of
    /// zero (where the switching ripple decides the dead-time voltage's sign), or `auto`
    /// (4 h v_dt / L from the fit); implies --horizon 1 unless a horizon is given. Needs
    /// --dead-time.
    #[arg(help_heading = "Inverter and cable", long, value_parser = parse_mask)]
    pub dead_time_mask: Option<crate::pmsm::DeadTimeMask>,
    /// DC-link voltage [V]: with --voltage reference, samples driven by a reference at the
    /// modulator's limit U_dc/√3 are weighted out.
    #[arg(help_heading = "Inverter and cable", long)]
    pub u_dc: Option<f64>,
    /// Known resistance in series with the winding (cable, connectors) [Ω]: subtracted, so
    /// r_s is the motor's alone.
    #[arg(help_heading = "Inverter and cable", long, default_value_t = 0.0)]
    pub cable_resistance: f64,
    /// Reference temperature T_0 [°C] of --r-s0 and --psi-f0: the report then derives the
    /// winding temperature (copper) and the magnet temperature (NdFeB).
    #[arg(help_heading = "Temperatures", long)]
    pub t0: Option<f64>,
    /// Winding resistance at T_0 [Ω] (with --t0).
    #[arg(help_heading = "Temperatures", long)]
    pub r_s0: Option<f64>,
    /// Magnet flux ψ_f at T_0 [V s] (with --t0).
    #[arg(help_heading = "Temperatures", long)]
    pub psi_f0: Option<f64>,
    /// Write the JSON report to this file ("-" for stdout, which suppresses the table).
    #[arg(help_heading = "Output", long)]
    pub json: Option<PathBuf>,
    /// What to print on stdout: the aligned table, the JSON report, or the table as Markdown.
    #[arg(help_heading = "Output", long, value_enum, default_value_t = FormatArg::Table)]
    pub format: FormatArg,
    /// Start values in model order, comma separated, SI units (default: linear least squares).
    #[arg(help_heading = "Start and parameters", long, value_delimiter = ',', allow_hyphen_values = true)]
    pub start: Option<Vec<f64>>,
    /// Parameters held fixed, comma separated: NAME at its start value (the least-squares
    /// estimate or --start), NAME=VALUE at a value in SI units (e.g. r_s=0.9,k_e).
    #[arg(help_heading = "Start and parameters", long, value_delimiter = ',', value_parser = parse_fix)]
    pub fix: Vec<(String, Option<f64>)>,
    /// Parameters estimated separately per log, comma separated (e.g. r_s).
    #[arg(help_heading = "Start and parameters", long, value_delimiter = ',')]
    pub per_log: Vec<String>,
    /// Optimiser: Levenberg-Marquardt (lm), damped Gauss-Newton with line search (gn),
    /// Levenberg-Marquardt with MINPACK's trust region (trust-region), or auto: the trust
    /// region on a static model whose Jacobian is kept (a flux map, mechanics, a curve
    /// fit), Levenberg-Marquardt otherwise.
    #[arg(help_heading = "Solver", long, value_parser = super::values::listed::<SolverKind>(), default_value = "auto")]
    pub solver: SolverKind,
    /// Parameter scaling.
    #[arg(help_heading = "Solver", long, value_parser = super::values::listed::<ScalingKind>(), default_value = "nominal")]
    pub scaling: ScalingKind,
    /// k-step-ahead prediction horizon in samples (default: output error, i.e. pure simulation).
    #[arg(help_heading = "Estimator", long)]
    pub horizon: Option<usize>,
    /// Sample weighting β(ω): uniform, low-speed:W0, high-speed:W0 or band:LO:HI[:FLOOR]
    /// (speeds mechanical, rad/s; thesis eq. 5.11).
    #[arg(help_heading = "Estimator", long, default_value = "uniform", value_parser = parse_weighting)]
    pub weighting: WeightingKind,
    /// Robust fit with Huber's loss, δ = C·σ̂ (C = 1.345 without a value). The value must be
    /// attached with `=` (--huber=2.0): a separate word is read as a log.
    #[arg(help_heading = "Estimator", long, value_name = "C", num_args = 0..=1, require_equals = true, default_missing_value = "1.345")]
    pub huber: Option<f64>,
    /// Output weights Λ for i_d, i_q, comma separated (default 1,1).
    #[arg(help_heading = "Estimator", long, value_delimiter = ',')]
    pub output_weights: Option<Vec<f64>>,
    /// Bounds of a parameter, NAME:LO:HI in SI units (repeatable), e.g. r_s:0.1:5.
    #[arg(help_heading = "Start and parameters", long, value_parser = parse_bounds)]
    pub bounds: Vec<(String, f64, f64)>,
    /// Take the first measured currents as the exact initial state instead of estimating it.
    #[arg(help_heading = "Start and parameters", long)]
    pub fixed_x0: bool,
    /// Low-pass prefilter cutoff [Hz], 4th-order Butterworth: on the residuals for pem
    /// (causal L(q)), on every signal for ls (zero-phase, forward-backward).
    #[arg(help_heading = "Estimator", long)]
    pub prefilter: Option<f64>,
    /// Estimation method: prediction error (pem), the linear least-squares regression of
    /// the voltage equations (ls; weighted by --weighting, filtered by --prefilter),
    /// instrumental variables on the exact inverse model (iv: for noise on the logged
    /// voltage or current, errors in variables; terminal voltage), or pem unless its fit
    /// finds the logged voltage's noise biasing it (voltage_noise_bias), then iv where the
    /// options allow it (auto).
    #[arg(help_heading = "Estimator", long, value_enum, default_value_t = Method::Auto)]
    pub method: Method,
    /// Maximum number of solver iterations.
    #[arg(help_heading = "Solver", long, default_value_t = Tolerances::default().max_iters)]
    pub max_iters: u64,
    /// Relative cost-reduction tolerance.
    #[arg(help_heading = "Solver", long, default_value = "1e-12")]
    pub ftol: f64,
    /// Step tolerance (scaled parameters).
    #[arg(help_heading = "Solver", long, default_value = "1e-10")]
    pub xtol: f64,
    /// Gradient tolerance (cosine between residual and Jacobian columns).
    #[arg(help_heading = "Solver", long, default_value = "1e-10")]
    pub gtol: f64,
    /// Do not print the table.
    #[arg(help_heading = "Output", long, short = 'q')]
    pub quiet: bool,
    // Plots and exports (issue 17).
    /// Write the fit plot (SVG) to this file: measured and simulated currents with the
    /// speed, residuals with ±2σ, their autocorrelation, the parameter trace and the
    /// estimates with 95 % intervals.
    #[arg(help_heading = "Output", long, value_name = "PATH.svg")]
    pub plot: Option<PathBuf>,
    /// Write t, <output>_measured, <output>_simulated, <output>_residual of every log (a
    /// `log` column with several) as CSV to this file [s, A].
    #[arg(help_heading = "Output", long, value_name = "PATH.csv")]
    pub residuals: Option<PathBuf>,
    /// The log-reading flags (columns, units, window, limits).
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// The switching-resolved PWM inverter's flags.
    #[command(flatten)]
    pub pwm: super::pwm_args::PwmArgs,
}

impl From<&FitArgs> for FitRequest {
    /// The request of the flags: every option that changes the fit; the outputs that need
    /// simulated currents (`--plot`, `--residuals`) named by their flags.
    fn from(a: &FitArgs) -> Self {
        let outputs = [("--plot", a.plot.is_some()), ("--residuals", a.residuals.is_some())];
        Self {
            pole_pairs: a.pole_pairs,
            model: a.model,
            control_period: a.control_period,
            precision: a.precision.clone(),
            hold: a.hold,
            voltage: a.voltage,
            delay: a.delay,
            advance: a.advance,
            speed_pll: a.speed_pll,
            dead_time: a.dead_time,
            dead_time_width: a.dead_time_width,
            dead_time_mask: a.dead_time_mask,
            u_dc: a.u_dc,
            cable_resistance: a.cable_resistance,
            t0: a.t0,
            r_s0: a.r_s0,
            psi_f0: a.psi_f0,
            start: a.start.clone(),
            fix: a.fix.clone(),
            per_log: a.per_log.clone(),
            solver: a.solver,
            scaling: a.scaling,
            horizon: a.horizon,
            weighting: a.weighting.clone(),
            huber: a.huber,
            output_weights: a.output_weights.clone(),
            bounds: a.bounds.clone(),
            fixed_x0: a.fixed_x0,
            prefilter: a.prefilter,
            method: a.method,
            tolerances: Tolerances { ftol: a.ftol, xtol: a.xtol, gtol: a.gtol, max_iters: a.max_iters },
            allow_unconverged: a.allow_unconverged,
            reading: a.columns.reading(),
            pwm: PwmRequest::from(&a.pwm),
            simulated_outputs: outputs
                .iter()
                .filter(|(_, given)| *given)
                .map(|(f, _)| f.to_string())
                .collect(),
        }
    }
}

/// Parses a value of type `T` by its `FromStr` (the application layer's words).
fn by_str<T: std::str::FromStr<Err = String>>(s: &str) -> Result<T, String> {
    s.parse()
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Wrap {
        #[command(flatten)]
        fit: FitArgs,
    }

    /// The tolerances' defaults are written out for `--help` (`1e-12`, not
    /// `0.000000000001`): they must stay the library's.
    #[test]
    fn tolerance_defaults_are_the_library_defaults() {
        let a = Wrap::parse_from(["greybox", "log.csv", "-p", "4"]).fit;
        let t = Tolerances::default();
        assert_eq!((a.ftol, a.xtol, a.gtol, a.max_iters), (t.ftol, t.xtol, t.gtol, t.max_iters));
    }

    /// `greybox fit LOG -p 4` asks for what the application layer's defaults are (the
    /// Python `fit` starts from them).
    #[test]
    fn the_flags_defaults_are_the_requests() {
        let a = Wrap::parse_from(["greybox", "log.csv", "-p", "4"]).fit;
        assert_eq!(FitRequest::from(&a), FitRequest::new(PolePairs::Given(4)));
    }
}
