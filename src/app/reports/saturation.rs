//! The saturated IPM model (Hinkkanen et al., IEEE Trans. Ind. Appl. 53(3) 2017) fitted to
//! drive logs beside the magnetically linear IPM fit that starts it: what `greybox
//! saturation` and Python's `saturation` ask ([`SaturationRequest`]) and its report
//! ([`saturation`]).

use super::report::Report;
use crate::app::LogReading;
use crate::error::Result;
use crate::pmsm::{CsvOptions, LogSource, PmsmFitOptions, SaturationExponents, fit_saturated};

/// A saturated fit as asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct SaturationRequest {
    /// Pole pairs n_p.
    pub pole_pairs: u32,
    /// The model's exponents (default 4, 2, 1, 0).
    pub exponents: SaturationExponents,
    /// How the logs are read (as a fit reads them).
    pub reading: LogReading,
}

impl SaturationRequest {
    /// The command line's defaults for a motor of `pole_pairs`.
    pub fn new(pole_pairs: u32) -> Self {
        Self {
            pole_pairs,
            exponents: SaturationExponents { s: 4, t: 2, u: 1, v: 0 },
            reading: LogReading::default(),
        }
    }
}

/// The saturated fit of `logs` (files or tables, fitted jointly) as `r` asks and its report (the linear fit,
/// the saturated fit, the model, the inductances at the logs' operating points); untrusted
/// as [`crate::pmsm::SaturatedFit::untrusted_reasons`] says.
///
/// # Errors
/// Bad paths, unreadable logs, a failed linear or saturated fit.
pub fn saturation(logs: &[LogSource<'_>], r: &SaturationRequest) -> Result<Report> {
    let csv = CsvOptions { pole_pairs: Some(r.pole_pairs), ..r.reading.csv.clone() };
    let logs = crate::app::read_sources(&r.reading, &csv, logs)?;
    let fit = fit_saturated(&logs, &PmsmFitOptions::new(r.pole_pairs), r.exponents)?;
    Ok(Report::new(fit.to_string(), &fit, fit.untrusted_reasons()))
}
