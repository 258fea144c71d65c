//! `greybox standstill`: `R_s`, the inductances and the inverter's voltage error from
//! locked-rotor logs (the power-up test of drive firmware), with the injection length for
//! `R_s` to ±1 % (issue 33).

use super::columns::ColumnArgs;
use super::output;
use crate::pmsm::{CsvOptions, StandstillOptions, WINDING_TEMPERATURE, fit_standstill};
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
    /// Write the fit as JSON ("-" for stdout).
    #[arg(long, value_name = "PATH.json")]
    pub json: Option<PathBuf>,
    /// Print nothing on stdout but the JSON (if it goes there).
    #[arg(long, short)]
    pub quiet: bool,
    /// Log columns and units (as `greybox fit`).
    #[command(flatten)]
    pub columns: ColumnArgs,
}

/// Runs `greybox standstill`; whether the fit is trusted (the gate of [`crate::estimate::fit`]).
///
/// # Errors
/// Unreadable logs, a bad width, a failed fit, an output that cannot be written (nothing is
/// written then).
pub fn run_standstill(a: &StandstillArgs) -> crate::Result<bool> {
    super::logs::check_paths(&a.logs)?;
    output::check_all(&[("--json", a.json.as_deref())], &a.logs)?;
    let mut csv = CsvOptions { pole_pairs: Some(a.pole_pairs), ..a.columns.options() };
    csv.columns.extra = vec![a.col_temperature.clone()];
    let logs: Vec<_> = a
        .columns
        .read_logs(&a.logs, &csv, false)?
        .into_iter()
        .flatten()
        .map(|e| renamed_channel(e, &a.col_temperature, WINDING_TEMPERATURE, "°C"))
        .collect::<crate::Result<_>>()?;
    let options = StandstillOptions {
        pole_pairs: a.pole_pairs,
        reference_delay: (!a.terminal).then_some(a.delay),
        width: a.width,
        ..StandstillOptions::default()
    };
    let fit = fit_standstill(&logs, &options)?;
    output::text_and_json(&fit.to_string(), &fit, a.json.as_deref(), a.quiet)?;
    let trusted = fit.fit.trusted();
    if !trusted {
        let codes: Vec<&str> =
            fit.fit.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.as_str()).collect();
        eprintln!("warning: the standstill fit is not to be trusted ({}); exit code 3", codes.join(", "));
    }
    Ok(trusted)
}

/// The log with its column `column` (if any) also under `name` \[`unit`\], the name the fit
/// reads.
///
/// # Errors
/// Those of [`crate::data::Experiment::with_channel`].
pub(super) fn renamed_channel(
    e: crate::data::Experiment,
    column: &str,
    name: &str,
    unit: &str,
) -> crate::Result<crate::data::Experiment> {
    match e.get(column) {
        Some(c) if column != name => {
            let channel = crate::data::Channel::new(name, unit, c.values.as_slice().to_vec());
            e.with_channel(channel)
        }
        _ => Ok(e),
    }
}
