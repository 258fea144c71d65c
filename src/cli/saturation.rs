//! `greybox saturation`: the saturated IPM model (Hinkkanen et al., IEEE Trans. Ind. Appl.
//! 53(3) 2017) fitted to drive logs, beside the magnetically linear IPM fit that starts it,
//! with the inductances at the logs' operating points (issue 33).

use super::columns::ColumnArgs;
use super::output;
use crate::app::{SaturationRequest, exponents, saturation};
use crate::pmsm::LogSource;
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
    #[arg(long, value_delimiter = ',', value_name = "S,T,U,V", default_value = "4,2,1,0")]
    pub exponents: Vec<u32>,
    /// The report's outputs.
    #[command(flatten)]
    pub report: output::ReportArgs,
    /// Log columns and units (as `greybox fit`).
    #[command(flatten)]
    pub columns: ColumnArgs,
}

impl TryFrom<&SaturationArgs> for SaturationRequest {
    type Error = crate::Error;

    /// The request of these flags.
    ///
    /// # Errors
    /// [`crate::Error::InvalidOption`] (`--exponents`) for bad exponents.
    fn try_from(a: &SaturationArgs) -> crate::Result<Self> {
        Ok(Self {
            pole_pairs: a.pole_pairs,
            exponents: exponents(&a.exponents)?,
            reading: a.columns.reading(),
        })
    }
}

/// Runs `greybox saturation`; whether the saturated fit is trusted
/// ([`crate::pmsm::SaturatedFit::trusted`]).
///
/// # Errors
/// Bad exponents, unreadable logs, a failed linear or saturated fit, an output that cannot
/// be written (nothing is written then).
pub fn run_saturation(a: &SaturationArgs) -> crate::Result<bool> {
    let r = SaturationRequest::try_from(a)?;
    a.report.run(&a.logs, "saturated fit", || saturation(&LogSource::files(&a.logs), &r))
}
