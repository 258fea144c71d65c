//! The names of a fit's options as the front ends spell them: the library names an option
//! by its field (`per_experiment`) or a phrase (`dead-time mask`); the request, the command
//! line and Python by the option's name (`per_log`: `--per-log`, `per_log=`).

/// The name of the fit's option that sets the library option `option` (its field name or
/// its phrase in [`crate::Error::InvalidOption`]), snake case (`per_log`; `t0/r_s0/psi_f0`
/// for the thermal reference's three; `LOG` for the logs themselves), or `None` when no
/// option of a fit sets it.
pub fn option_of(option: &str) -> Option<&'static str> {
    Some(match option {
        "per_experiment" => "per_log",
        "fixed" => "fix",
        "bounds" => "bounds",
        "start" => "start",
        "huber" => "huber",
        "hold" => "hold",
        "voltage" => "voltage",
        "voltage_limit" => "u_dc",
        "weighting" => "weighting",
        "prefilter" | "cutoff" => "prefilter",
        "max_iters" => "max_iters",
        "output_weights" => "output_weights",
        "horizon" => "horizon",
        "thermal" => "t0/r_s0/psi_f0",
        "experiments" => "LOG",
        "model" | "salient" => "model",
        "dead-time width" => "dead_time_width",
        "dead-time mask" => "dead_time_mask",
        "pole-pairs" => "pole_pairs",
        "method" => "method",
        "dead-time" => "dead_time",
        "t0" => "t0",
        "ftol" => "ftol",
        "xtol" => "xtol",
        "gtol" => "gtol",
        "output" => "json",
        _ => return None,
    })
}
