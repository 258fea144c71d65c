//! `R_s`, the inductances and the inverter's voltage error from locked-rotor logs (the
//! power-up test of drive firmware): what `greybox standstill` and Python's `standstill`
//! ask ([`StandstillRequest`]) and its report ([`standstill`]).

use super::report::{Report, read_with_channel};
use crate::app::LogReading;
use crate::error::Result;
use crate::pmsm::{LogSource, StandstillOptions, WINDING_TEMPERATURE, fit_standstill};

/// A standstill fit as asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct StandstillRequest {
    /// Pole pairs n_p.
    pub pole_pairs: u32,
    /// Fit from the measured terminal voltage (`ud, uq`) instead of the reference.
    pub terminal: bool,
    /// Samples between the reference's computation and its application (default 1).
    pub delay: usize,
    /// Width \[A\] of the inverter error's smooth sign; `None`: 2 % of the largest current.
    pub width: Option<f64>,
    /// Column of the winding temperature \[°C\], used when present (then `r_s` is the
    /// resistance at 20 °C).
    pub col_temperature: String,
    /// How the logs are read (as a fit reads them).
    pub reading: LogReading,
}

impl StandstillRequest {
    /// The command line's defaults for a motor of `pole_pairs`.
    pub fn new(pole_pairs: u32) -> Self {
        Self {
            pole_pairs,
            terminal: false,
            delay: 1,
            width: None,
            col_temperature: WINDING_TEMPERATURE.into(),
            reading: LogReading::default(),
        }
    }
}

/// The standstill fit of `logs` (files or tables, fitted jointly) as `r` asks and its report (the fit, the
/// axes, the injection length for `R_s` to ±1 %); untrusted as the fit's gate says
/// (`segments_disagree` when the logs' halves disagree: docs/standstill.md).
///
/// # Errors
/// Bad paths, unreadable logs, a bad width, a failed fit.
pub fn standstill(logs: &[LogSource<'_>], r: &StandstillRequest) -> Result<Report> {
    let extra = (r.col_temperature.as_str(), WINDING_TEMPERATURE, "°C");
    let logs = read_with_channel(logs, &r.reading, r.pole_pairs, extra)?;
    let options = StandstillOptions {
        pole_pairs: r.pole_pairs,
        reference_delay: (!r.terminal).then_some(r.delay),
        width: r.width,
        ..StandstillOptions::default()
    };
    let fit = fit_standstill(&logs, &options)?;
    Ok(Report::new(fit.to_string(), &fit, fit.fit.untrusted_codes()))
}
