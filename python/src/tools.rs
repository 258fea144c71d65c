//! The fits of issue 33 (`fluxmap`, `saturation`, `standstill`, `mechanics`): Python
//! keywords to the application layer's typed requests ([`greybox::app::FluxMapRequest`],
//! …; each keyword converted once, a wrong one refused naming it), run by the library's
//! [`greybox::app::fluxmap`], … with the GIL released.

use crate::errors::{OptionError, to_py};
use crate::fit::Source;
use crate::keyword::{Value, each};
use crate::reading::{Keywords, ReadingKeys};
use crate::words::in_python_words;
use greybox::app::{
    FluxMapRequest, LogReading, MechanicsRequest, Report, SaturationRequest, StandstillRequest, exponents,
};
use greybox::data::Delimiter;
use greybox::pmsm::LogSource;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The command line's file outputs of the four commands, which the functions return instead.
const OUTPUTS: &[&str] = &["json", "quiet"];

/// What the functions return instead of writing the outputs.
const RETURNS: &str = "the function returns the report";

/// The keywords of `fluxmap` (in the order `greybox fluxmap --help` lists them).
const FLUXMAP: Keywords = Keywords {
    command: "fluxmap",
    doc: "docs/saturation.md",
    example: "exponents=(4, 2, 1, 0)",
    own: &["exponents", "col_id", "col_iq", "col_psid", "col_psiq", "col_torque", "pole_pairs", "delimiter"],
    reading: false,
    outputs: OUTPUTS,
    returns: RETURNS,
};

/// The keywords of `saturation`.
const SATURATION: Keywords = Keywords {
    command: "saturation",
    doc: "docs/saturation.md",
    example: "exponents=(4, 2, 1, 0)",
    own: &["pole_pairs", "exponents"],
    reading: true,
    outputs: OUTPUTS,
    returns: RETURNS,
};

/// The keywords of `standstill`.
const STANDSTILL: Keywords = Keywords {
    command: "standstill",
    doc: "docs/standstill.md",
    example: "terminal=True",
    own: &["pole_pairs", "terminal", "delay", "width", "col_temperature"],
    reading: true,
    outputs: OUTPUTS,
    returns: RETURNS,
};

/// The keywords of `mechanics`.
const MECHANICS: Keywords = Keywords {
    command: "mechanics",
    doc: "docs/mechanics.md",
    example: "k_t=0.6",
    own: &[
        "pole_pairs",
        "k_t",
        "lead",
        "pole_pitch",
        "k_f",
        "gravity",
        "constant_load",
        "per_log",
        "window",
        "coulomb_speed",
        "col_load",
    ],
    reading: true,
    outputs: OUTPUTS,
    returns: RETURNS,
};

/// Runs the fit `command` (`fluxmap`: one map; `saturation`, `standstill`, `mechanics`: logs
/// fitted jointly; each a path or an Arrow table named by `names` in its place, read in
/// memory as `fit` reads them) with the keyword `options`, as the command
/// line's subcommand of that name does, the GIL released: its JSON report (as `--json`
/// writes it) and the codes of the reasons it is not to be trusted (empty: trusted; the
/// command line's exit code 3 otherwise).
///
/// Errors: `OptionError` naming the keyword (an unknown command or keyword, a bad value, a
/// file output; not one map), `DataError` (a log that is neither a path nor an
/// Arrow table, or cannot be read), `FitError`.
#[pyfunction]
pub fn report(
    py: Python<'_>,
    command: &str,
    sources: Vec<Bound<'_, PyAny>>,
    names: Vec<String>,
    options: &Bound<'_, PyDict>,
) -> PyResult<(String, Vec<String>)> {
    let sources = Source::all(&sources, names)?;
    let run: Box<Run> = match command {
        "fluxmap" => {
            let r = fluxmap_request(options)?;
            if sources.len() != 1 {
                return Err(OptionError::new_err("map: one flux map (a path or a table)"));
            }
            Box::new(move |maps| greybox::app::fluxmap(maps[0], &r))
        }
        "saturation" => {
            let r = saturation_request(options)?;
            Box::new(move |logs| greybox::app::saturation(logs, &r))
        }
        "standstill" => {
            let r = standstill_request(options)?;
            Box::new(move |logs| greybox::app::standstill(logs, &r))
        }
        "mechanics" => {
            let r = mechanics_request(options)?;
            Box::new(move |logs| greybox::app::mechanics(logs, &r))
        }
        other => {
            return Err(OptionError::new_err(format!(
                "command `{other}`: one of fluxmap, saturation, standstill, mechanics"
            )));
        }
    };
    let r = py
        .detach(|| run(&sources.iter().map(Source::log_source).collect::<Vec<_>>()))
        .map_err(|e| to_py(in_python_words(e)))?;
    Ok((r.json, r.untrusted))
}

/// A report command with its request, run on the logs.
type Run = dyn FnOnce(&[LogSource<'_>]) -> greybox::Result<Report> + Send;

/// The keyword `pole_pairs`, required by the commands that read drive logs.
fn pole_pairs(given: Option<u32>) -> PyResult<u32> {
    given.ok_or_else(|| OptionError::new_err("pole_pairs: required (the motor's pole pairs n_p)"))
}

/// `exponents=(S, T, U, V)` (or `"S,T,U,V"`), checked.
fn exponents_of(x: &Value<'_, '_>) -> PyResult<greybox::pmsm::SaturationExponents> {
    let values =
        x.items()?.iter().map(|v| Value { key: x.key, v }.count()).collect::<PyResult<Vec<u32>>>()?;
    exponents(&values)
        .map_err(|_| x.err("expected four whole numbers (S, T, U, V) with S, T ≥ 1, e.g. (4, 2, 1, 0)"))
}

/// The request of `fluxmap`'s keywords.
fn fluxmap_request(options: &Bound<'_, PyDict>) -> PyResult<FluxMapRequest> {
    let mut r = FluxMapRequest::default();
    each(options, |x| {
        let c = &mut r.columns;
        match x.key {
            "exponents" => r.exponents = Some(exponents_of(x)?),
            "col_id" => c.i_d = x.text()?,
            "col_iq" => c.i_q = x.text()?,
            "col_psid" => c.psi_d = x.text()?,
            "col_psiq" => c.psi_q = x.text()?,
            "col_torque" => c.torque = x.text()?,
            "pole_pairs" => r.pole_pairs = Some(positive_count(x)?),
            "delimiter" => c.delimiter = x.parsed(|s| s.parse::<Delimiter>().map_err(|e| e.to_string()))?,
            other => return Err(FLUXMAP.not_taken(other)),
        }
        Ok(())
    })?;
    Ok(r)
}

/// A whole number ≥ 1.
fn positive_count(x: &Value<'_, '_>) -> PyResult<u32> {
    match x.count()? {
        0 => Err(x.err("expected a whole number ≥ 1")),
        n => Ok(n),
    }
}

/// The keywords of a command that reads drive logs (`keywords`): `pole_pairs` (required)
/// and the reading's taken here, the command's own by `own` (`false`: not one of its own).
fn logs_command(
    options: &Bound<'_, PyDict>,
    keywords: &Keywords,
    mut own: impl FnMut(&Value<'_, '_>) -> PyResult<bool>,
) -> PyResult<(u32, LogReading)> {
    let (mut n_p, mut reading) = (None, ReadingKeys::new(LogReading::default().csv));
    each(options, |x| {
        match x.key {
            "pole_pairs" => n_p = Some(x.count()?),
            _ if own(x)? => {}
            other if reading.take(other, x)? => {}
            other => return Err(keywords.not_taken(other)),
        }
        Ok(())
    })?;
    Ok((pole_pairs(n_p)?, reading.finish()?))
}

/// The request of `saturation`'s keywords.
fn saturation_request(options: &Bound<'_, PyDict>) -> PyResult<SaturationRequest> {
    let mut r = SaturationRequest::new(0);
    let (pole_pairs, reading) = logs_command(options, &SATURATION, |x| {
        match x.key {
            "exponents" => r.exponents = exponents_of(x)?,
            _ => return Ok(false),
        }
        Ok(true)
    })?;
    Ok(SaturationRequest { pole_pairs, reading, ..r })
}

/// The request of `standstill`'s keywords.
fn standstill_request(options: &Bound<'_, PyDict>) -> PyResult<StandstillRequest> {
    let mut r = StandstillRequest::new(0);
    let (pole_pairs, reading) = logs_command(options, &STANDSTILL, |x| {
        match x.key {
            "terminal" => r.terminal = x.flag()?,
            "delay" => r.delay = x.count()?,
            "width" => r.width = Some(x.number()?),
            "col_temperature" => r.col_temperature = x.text()?,
            _ => return Ok(false),
        }
        Ok(true)
    })?;
    Ok(StandstillRequest { pole_pairs, reading, ..r })
}

/// The request of `mechanics`' keywords.
fn mechanics_request(options: &Bound<'_, PyDict>) -> PyResult<MechanicsRequest> {
    let mut r = MechanicsRequest::new(0);
    let (pole_pairs, reading) = logs_command(options, &MECHANICS, |x| {
        match x.key {
            "k_t" => r.k_t = Some(x.number()?),
            "lead" => r.lead = Some(x.number()?),
            "pole_pitch" => r.pole_pitch = Some(x.number()?),
            "k_f" => r.k_f = Some(x.number()?),
            "gravity" => r.gravity = x.flag()?,
            "constant_load" => r.constant_load = x.flag()?,
            "per_log" => r.per_log = x.flag()?,
            "window" => r.window = x.number()?,
            "coulomb_speed" => {
                r.coulomb_speed = match x.word()?.as_str() {
                    "estimate" => None,
                    _ => Some(x.number().ok().filter(|w| *w > 0.0).ok_or_else(|| {
                        x.err("expected a positive speed in rad/s (m/s on a linear axis) or \"estimate\"")
                    })?),
                }
            }
            "col_load" => r.col_load = x.text()?,
            _ => return Ok(false),
        }
        Ok(true)
    })?;
    Ok(MechanicsRequest { pole_pairs, reading, ..r })
}
