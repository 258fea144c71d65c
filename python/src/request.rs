//! Python keywords to the application layer's typed [`FitRequest`]: each keyword converted
//! once, by the same words the command line accepts ([`Choice`], the values' `FromStr`), and
//! a wrong one refused naming the keyword (`voltage="referense": expected actual or
//! reference`), an unknown one with the keywords that exist.

use crate::errors::OptionError;
use crate::keyword::Value;
use greybox::app::values::{parse_bounds, parse_fix, parse_mask, parse_weighting};
use greybox::app::{FitRequest, LogReading, PolePairs, PwmRequest};
use greybox::data::Delimiter;
use greybox::pmsm::{ColumnNames, DqSource};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyInt};
use std::path::PathBuf;

/// The keywords of `fit` and `fit_many` that set a fit's options, in the order `--help`
/// lists their flags' groups.
pub const FIT_KEYWORDS: &[&str] = &[
    "pole_pairs",
    "model",
    "control_period",
    "hold",
    "voltage",
    "delay",
    "advance",
    "speed_pll",
    "dead_time",
    "dead_time_width",
    "dead_time_mask",
    "u_dc",
    "cable_resistance",
    "t0",
    "r_s0",
    "psi_f0",
    "start",
    "fix",
    "per_log",
    "solver",
    "scaling",
    "horizon",
    "weighting",
    "huber",
    "output_weights",
    "bounds",
    "fixed_x0",
    "prefilter",
    "method",
    "max_iters",
    "ftol",
    "xtol",
    "gtol",
    "allow_unconverged",
    "col_t",
    "col_ud",
    "col_uq",
    "col_id",
    "col_iq",
    "col_w",
    "col_theta",
    "col_ud_ref",
    "col_uq_ref",
    "col_i_abc",
    "col_u_abc",
    "columns",
    "speed_unit",
    "angle_unit",
    "speed_frame",
    "negate_speed",
    "current_scale",
    "voltage_scale",
    "dq_from_phases",
    "time_unit",
    "from",
    "to",
    "split_gaps",
    "force",
    "max_line_bytes",
    "max_fields",
    "max_rows",
    "delimiter",
    "inverter",
    "modulator",
    "pwm_update",
    "carrier_hz",
    "pwm_levels",
    "carrier_first",
    "leg_state_width",
    "predictor_gain",
    "inverter_params",
];

/// The command line's file outputs, which the Python functions do not write.
const OUTPUTS: &[&str] = &["json", "plot", "residuals", "each", "summary", "trend", "format", "quiet"];

/// The request of `options` (keyword → value; `None` values are left at their default),
/// starting from the command line's defaults with `--pole-pairs` required.
///
/// Errors: `OptionError` naming the keyword: unknown, a file output, a bad value, or
/// `columns` with a `col_*` keyword.
pub fn fit_request(options: &Bound<'_, PyDict>) -> PyResult<FitRequest> {
    let mut r = FitRequest::new(PolePairs::Auto);
    let mut pole_pairs = false;
    let mut names = ColumnNames::default();
    let (mut dq_from_phases, mut split_gaps) = (false, false);
    let mut renamed: Vec<String> = Vec::new();
    let mut columns: Option<Vec<(String, String)>> = None;
    let mut csv = r.reading.csv.clone();
    let mut pwm = PwmRequest::default();
    for (k, v) in options.iter() {
        let key: String = k.extract()?;
        if v.is_none() {
            continue;
        }
        let x = Value { key: &key, v: &v };
        match key.as_str() {
            "pole_pairs" => {
                r.pole_pairs = if v.is_instance_of::<PyInt>() && !v.is_instance_of::<PyBool>() {
                    PolePairs::Given(x.count()?)
                } else {
                    x.parsed(str::parse::<PolePairs>)?
                };
                pole_pairs = true;
            }
            "model" => r.model = x.choice()?,
            "control_period" => r.control_period = Some(x.number()?),
            "hold" => r.hold = x.choice()?,
            "voltage" => r.voltage = x.choice()?,
            "delay" => r.delay = x.parsed(str::parse)?,
            "advance" => r.advance = x.parsed(str::parse)?,
            "speed_pll" => r.speed_pll = Some(x.parsed(str::parse)?),
            "dead_time" => r.dead_time = x.parsed(str::parse)?,
            "dead_time_width" => r.dead_time_width = Some(x.parsed(greybox::app::Pll::width)?),
            "dead_time_mask" => r.dead_time_mask = Some(x.parsed(parse_mask)?),
            "u_dc" => r.u_dc = Some(x.number()?),
            "cable_resistance" => r.cable_resistance = x.number()?,
            "t0" => r.t0 = Some(x.number()?),
            "r_s0" => r.r_s0 = Some(x.number()?),
            "psi_f0" => r.psi_f0 = Some(x.number()?),
            "start" => r.start = Some(x.numbers()?),
            "fix" => {
                r.fix =
                    x.pairs()?.iter().map(|s| parse_fix(s).map_err(|e| x.err(&e))).collect::<PyResult<_>>()?
            }
            "per_log" => r.per_log = x.texts()?,
            "solver" => r.solver = x.choice()?,
            "scaling" => r.scaling = x.choice()?,
            "horizon" => r.horizon = Some(x.count()?),
            "weighting" => r.weighting = x.parsed(parse_weighting)?,
            "huber" => {
                r.huber = Some(if v.is_instance_of::<PyBool>() && x.flag()? { 1.345 } else { x.number()? })
            }
            "output_weights" => r.output_weights = Some(x.numbers()?),
            "bounds" => {
                r.bounds = x
                    .pairs()?
                    .iter()
                    .map(|s| parse_bounds(s).map_err(|e| x.err(&e)))
                    .collect::<PyResult<_>>()?
            }
            "fixed_x0" => r.fixed_x0 = x.flag()?,
            "prefilter" => r.prefilter = Some(x.number()?),
            "method" => r.method = x.choice()?,
            "max_iters" => r.tolerances.max_iters = x.count()?,
            "ftol" => r.tolerances.ftol = x.number()?,
            "xtol" => r.tolerances.xtol = x.number()?,
            "gtol" => r.tolerances.gtol = x.number()?,
            "allow_unconverged" => r.allow_unconverged = x.flag()?,
            "col_t" | "col_ud" | "col_uq" | "col_id" | "col_iq" | "col_w" | "col_theta" | "col_ud_ref"
            | "col_uq_ref" => {
                let standard =
                    greybox::app::columns::RENAMEABLE.iter().find(|(_, o)| *o == key).map(|(s, _)| *s);
                if let Some(slot) = standard.and_then(|s| names.column_mut(s)) {
                    *slot = x.text()?;
                }
                renamed.push(key.clone());
            }
            "col_i_abc" => {
                [names.i_a, names.i_b, names.i_c] = x.three()?;
                renamed.push(key.clone());
            }
            "col_u_abc" => {
                [names.u_a, names.u_b, names.u_c] = x.three()?;
                renamed.push(key.clone());
            }
            "columns" => columns = Some(column_map(&x)?),
            "speed_unit" => csv.speed_unit = x.choice()?,
            "angle_unit" => csv.angle_unit = x.choice()?,
            "speed_frame" => csv.speed_frame = x.choice()?,
            "negate_speed" => csv.negate_speed = x.flag()?,
            "current_scale" => csv.current_scale = x.choice()?,
            "voltage_scale" => csv.voltage_scale = x.choice()?,
            "dq_from_phases" => dq_from_phases = x.flag()?,
            "time_unit" => csv.time_unit = x.choice()?,
            "from" => csv.window.from = x.optional_number()?,
            "to" => csv.window.to = x.optional_number()?,
            "split_gaps" => split_gaps = x.flag()?,
            "force" => csv.force = x.flag()?,
            "max_line_bytes" => csv.limits.max_line_bytes = x.count()?,
            "max_fields" => csv.limits.max_fields = x.count()?,
            "max_rows" => csv.limits.max_rows = x.count()?,
            "delimiter" => csv.delimiter = x.parsed(|s| s.parse::<Delimiter>().map_err(|e| e.to_string()))?,
            "inverter" => pwm.inverter = x.choice()?,
            "modulator" => pwm.modulator = x.choice()?,
            "pwm_update" => pwm.pwm_update = x.choice()?,
            "carrier_hz" => pwm.carrier_hz = Some(x.number()?),
            "pwm_levels" => pwm.pwm_levels = Some(x.count()?),
            "carrier_first" => pwm.carrier_first = Some(x.choice()?),
            "leg_state_width" => pwm.leg_state_width = Some(x.parsed(str::parse)?),
            "predictor_gain" => pwm.predictor_gain = Some(x.parsed(str::parse)?),
            "inverter_params" => pwm.inverter_params = Some(PathBuf::from(v.str()?.to_string())),
            other if OUTPUTS.contains(&other) => {
                return Err(crate::errors::refused(
                    other,
                    "the Python functions write no files: use Fit.to_json(), Fit.svg(), fit_many() for a summary",
                ));
            }
            other => return Err(unknown(other)),
        }
    }
    if !pole_pairs {
        return Err(OptionError::new_err("pole_pairs: required (a whole number, or \"auto\")"));
    }
    if let Some(map) = columns {
        if let Some(first) = renamed.first() {
            return Err(OptionError::new_err(format!(
                "columns: not together with {first} (name every column in `columns`, or each in its col_* keyword)"
            )));
        }
        for (standard, name) in map {
            if let Some(slot) = names.column_mut(&standard) {
                *slot = name;
            }
        }
    }
    csv.columns = names;
    csv.source = if dq_from_phases { DqSource::Phases } else { DqSource::Dq };
    r.reading = LogReading { csv, split_gaps };
    r.pwm = pwm;
    Ok(r)
}

/// `columns={"id": "Id", …}`: standard names (those of [`ColumnNames::STANDARD`]) to
/// header names, each standard name once.
fn column_map(x: &Value<'_, '_>) -> PyResult<Vec<(String, String)>> {
    let Ok(map) = x.v.cast::<PyDict>() else {
        return Err(x.err("expected a dict of standard name to header name, e.g. {\"id\": \"Id\"}"));
    };
    let mut out: Vec<(String, String)> = Vec::new();
    for (k, v) in map.iter() {
        let standard: String = Value { key: x.key, v: &k }.text()?;
        let name: String = Value { key: x.key, v: &v }.text()?;
        if !ColumnNames::STANDARD.contains(&standard.as_str()) {
            return Err(x.err(&format!(
                "`{standard}` is not a standard column name; one of {}",
                ColumnNames::STANDARD.join(", ")
            )));
        }
        if name.is_empty() {
            return Err(x.err(&format!("the header name of `{standard}` is empty")));
        }
        out.push((standard, name));
    }
    Ok(out)
}

/// The error of an unknown keyword, with the closest known ones.
fn unknown(key: &str) -> PyErr {
    let close: Vec<&str> = FIT_KEYWORDS.iter().copied().filter(|k| distance(k, key) <= 2).collect();
    let hint = if close.is_empty() {
        "the keywords are the flags of `greybox fit` (docs/options.md), e.g. voltage=\"reference\""
            .to_string()
    } else {
        format!("did you mean {}?", close.join(" or "))
    };
    OptionError::new_err(format!("unknown keyword `{key}`: {hint}"))
}

/// Levenshtein distance of two short names.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}
