//! `greybox saturation`: the saturated IPM model (Hinkkanen et al., IEEE Trans. Ind. Appl.
//! 53(3) 2017) fitted to drive logs, beside the magnetically linear IPM fit that starts it,
//! with the inductances at the logs' operating points (issue 33).

use super::columns::ColumnArgs;
use super::fluxmap::parse_exponents;
use super::output;
use crate::pmsm::{CsvOptions, PmsmFitOptions, SaturationExponents, fit_saturated};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `greybox saturation`.
#[derive(Args, Debug)]
#[command(
    after_help = "The logs are read as by `greybox fit` (terminal voltage, mechanical speed) and fitted \
jointly. The exponents are part of the model: take them from a flux-map fit (`greybox fluxmap`) of the same \
machine type, or compare the fits of a few. See docs/saturation.md."
)]
pub struct SaturationArgs {
    /// Drive logs (CSV, plain or gzip; Parquet, Arrow IPC), fitted jointly.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Number of pole pairs n_p of the motor.
    #[arg(long, short = 'p')]
    pub pole_pairs: u32,
    /// The exponents S,T,U,V of the saturation model.
    #[arg(long, value_delimiter = ',', num_args = 4, value_name = "S,T,U,V", default_values_t = [4, 2, 1, 0])]
    pub exponents: Vec<u32>,
    /// The report's outputs.
    #[command(flatten)]
    pub report: output::ReportArgs,
    /// Log columns and units (as `greybox fit`).
    #[command(flatten)]
    pub columns: ColumnArgs,
}

/// Runs `greybox saturation`; whether the saturated fit is trusted
/// ([`crate::pmsm::SaturatedFit::trusted`]).
///
/// # Errors
/// Unreadable logs, bad exponents, a failed linear or saturated fit, an output that cannot
/// be written (nothing is written then).
pub fn run_saturation(a: &SaturationArgs) -> crate::Result<bool> {
    a.report.run(&a.logs, "saturated fit", || saturation_outcome(a))
}

/// The fits of `greybox saturation` and their reports, nothing printed or written.
///
/// # Errors
/// As [`run_saturation`] but for the output.
pub fn saturation_outcome(a: &SaturationArgs) -> crate::Result<output::Outcome> {
    let exponents: SaturationExponents = parse_exponents(&a.exponents)?;
    let csv = CsvOptions { pole_pairs: Some(a.pole_pairs), ..a.columns.options() };
    let logs: Vec<_> = a.columns.read_logs(&a.logs, &csv, false)?.into_iter().flatten().collect();
    let fit = fit_saturated(&logs, &PmsmFitOptions::new(a.pole_pairs), exponents)?;
    Ok(output::Outcome::new(fit.to_string(), &fit, fit.untrusted_reasons()))
}
