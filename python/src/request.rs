//! Python keywords to the application layer's typed [`FitRequest`]: each keyword converted
//! once, by the same words the command line accepts ([`Choice`], the values' `FromStr`), and
//! a wrong one refused naming the keyword (`voltage="referense": expected actual or
//! reference`), an unknown one with the keywords that exist.

use crate::errors::OptionError;
use crate::keyword::each;
use crate::reading::{Keywords, ReadingKeys};
use greybox::app::values::{parse_bounds, parse_fix, parse_mask, parse_precision, parse_weighting};
use greybox::app::{FitRequest, PolePairs, PwmRequest};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyInt};
use std::path::PathBuf;

/// The keywords of `fit` and `fit_many` that set a fit's options, in the order `--help`
/// lists their flags' groups, besides the reading's ([`crate::reading::READING_KEYWORDS`]).
pub const FIT_KEYWORDS: &[&str] = &[
    "pole_pairs",
    "model",
    "control_period",
    "precision",
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

/// The keywords of `fit` and `fit_many`.
const FIT: Keywords = Keywords {
    command: "fit",
    doc: "docs/options.md",
    example: "voltage=\"reference\"",
    own: FIT_KEYWORDS,
    reading: true,
    outputs: &["json", "plot", "residuals", "each", "summary", "trend", "format", "quiet"],
    returns: "use Fit.to_json(), Fit.svg(), fit_many() for a summary",
};

/// The request of `options` (keyword → value; `None` values are left at their default),
/// starting from the command line's defaults with `--pole-pairs` required.
///
/// Errors: `OptionError` naming the keyword: unknown, a file output, a bad value, or
/// `columns` with a `col_*` keyword.
pub fn fit_request(options: &Bound<'_, PyDict>) -> PyResult<FitRequest> {
    let mut r = FitRequest::new(PolePairs::Auto);
    let mut pole_pairs = false;
    let mut reading = ReadingKeys::new(r.reading.csv.clone());
    let mut pwm = PwmRequest::default();
    each(options, |x| {
        match x.key {
            "pole_pairs" => {
                r.pole_pairs = if x.v.is_instance_of::<PyInt>() && !x.v.is_instance_of::<PyBool>() {
                    PolePairs::Given(x.count()?)
                } else {
                    x.parsed(str::parse::<PolePairs>)?
                };
                pole_pairs = true;
            }
            "model" => r.model = x.choice()?,
            "control_period" => r.control_period = Some(x.number()?),
            "precision" => r.precision = Some(parse_precision(&x.pairs()?.join(",")).map_err(|e| x.err(&e))?),
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
                r.huber = Some(if x.v.is_instance_of::<PyBool>() && x.flag()? { 1.345 } else { x.number()? })
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
            "inverter" => pwm.inverter = x.choice()?,
            "modulator" => pwm.modulator = x.choice()?,
            "pwm_update" => pwm.pwm_update = x.choice()?,
            "carrier_hz" => pwm.carrier_hz = Some(x.number()?),
            "pwm_levels" => pwm.pwm_levels = Some(x.count()?),
            "carrier_first" => pwm.carrier_first = Some(x.choice()?),
            "leg_state_width" => pwm.leg_state_width = Some(x.parsed(str::parse)?),
            "predictor_gain" => pwm.predictor_gain = Some(x.parsed(str::parse)?),
            "inverter_params" => pwm.inverter_params = Some(PathBuf::from(x.v.str()?.to_string())),
            other if reading.take(other, x)? => {}
            other => return Err(FIT.not_taken(other)),
        }
        Ok(())
    })?;
    if !pole_pairs {
        return Err(OptionError::new_err("pole_pairs: required (a whole number, or \"auto\")"));
    }
    r.reading = reading.finish()?;
    r.pwm = pwm;
    Ok(r)
}
