//! `greybox standstill`: `R_s`, the inductances and the inverter's voltage error from
//! locked-rotor logs (the power-up test of drive firmware), with the injection length for
//! `R_s` to ±1 % (issue 33).

use super::columns::ColumnArgs;
use super::output;
use crate::app::{StandstillRequest, standstill};
use crate::pmsm::{LogSource, WINDING_TEMPERATURE};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `greybox standstill`.
#[derive(Args, Debug)]
#[command(
    after_help = "The rotor must not turn (a brake, or d-axis injection at the rotor angle). The fit uses the \
reference voltage (ud_ref, uq_ref) applied --delay samples later and estimates the inverter's voltage error \
v_dt, or with --terminal the measured voltage (ud, uq). Inject steps of two current levels of each sign so \
that R_s and v_dt separate. A winding-temperature column (--col-temperature) makes r_s the resistance at \
20 °C. See docs/standstill.md."
)]
pub struct StandstillArgs {
    /// Locked-rotor logs (CSV, plain or gzip; Parquet, Arrow IPC), fitted jointly.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Number of pole pairs n_p of the motor.
    #[arg(long, short = 'p')]
    pub pole_pairs: u32,
    /// Fit from the measured terminal voltage (ud, uq) instead of the reference.
    #[arg(long)]
    pub terminal: bool,
    /// Samples between the reference's computation and its application.
    #[arg(long, default_value_t = 1)]
    pub delay: usize,
    /// Width [A] of the inverter error's smooth sign (default: 2 % of the largest current).
    #[arg(long, value_name = "A")]
    pub width: Option<f64>,
    /// Column of the winding temperature [°C], used when present.
    #[arg(long, default_value = WINDING_TEMPERATURE, value_name = "NAME")]
    pub col_temperature: String,
    /// The report's outputs.
    #[command(flatten)]
    pub report: output::ReportArgs,
    /// Log columns and units (as `greybox fit`).
    #[command(flatten)]
    pub columns: ColumnArgs,
}

impl From<&StandstillArgs> for StandstillRequest {
    /// The request of these flags.
    fn from(a: &StandstillArgs) -> Self {
        Self {
            pole_pairs: a.pole_pairs,
            terminal: a.terminal,
            delay: a.delay,
            width: a.width,
            col_temperature: a.col_temperature.clone(),
            reading: a.columns.reading(),
        }
    }
}

/// Runs `greybox standstill`; whether the fit is trusted (the gate of [`crate::estimate::fit`]).
///
/// # Errors
/// Unreadable logs, a bad width, a failed fit, an output that cannot be written (nothing is
/// written then).
pub fn run_standstill(a: &StandstillArgs) -> crate::Result<bool> {
    a.report.run(&a.logs, "standstill fit", || {
        standstill(&LogSource::files(&a.logs), &StandstillRequest::from(a))
    })
}
