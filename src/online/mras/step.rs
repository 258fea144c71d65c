//! The observers' model of the machine (see the parent module's documentation): the
//! observer crate's [`greybox_observer::Machine`], surface magnets in closed form or the
//! salient step by its augmented exponential with its sensitivities; and the conversions
//! between the crate's types and the observer crate's.

use super::super::config::{Adaptation, MrasConfig};
use super::sample::Sample;
use crate::error::{Error, Result};
use greybox_observer::{Field, Settings, StepError};

/// The observers' model: surface magnets in closed form, or a salient machine.
pub(crate) type Machine = greybox_observer::Machine<f64>;

/// The model of `config` (validated; `settings` its observer crate's settings): the salient
/// step when [`MrasConfig::salient`] (`l_s` is `L_d`), else the surface-magnet one. Both
/// observers build theirs here.
///
/// # Errors
/// A bad `l_q` ([`Error::InvalidOption`]).
pub(crate) fn machine(config: &MrasConfig, settings: &Settings<f64>) -> Result<Machine> {
    greybox_observer::Machine::of(settings, config.l_q.filter(|_| config.salient())).map_err(invalid)
}

/// A failed step of the model as the crate's error, in `context`.
pub(crate) fn step_error(context: String, e: StepError) -> Error {
    Error::Numerical { context, reason: e.to_string() }
}

/// The observer crate's settings of `config`.
pub(crate) fn settings(config: &MrasConfig) -> Settings<f64> {
    Settings {
        n_p: config.n_p,
        hold: config.hold.into(),
        adaptation: match config.adaptation {
            Adaptation::Lyapunov => greybox_observer::Adaptation::Lyapunov,
            Adaptation::Relay => greybox_observer::Adaptation::Relay,
            Adaptation::Normalised => greybox_observer::Adaptation::Normalised,
        },
        l_s: config.l_s,
        h: config.h,
        f: config.f,
        gamma_ke: config.gamma_ke,
        gamma_rs: config.gamma_rs,
        tau_ke: config.tau_ke,
        tau_rs: config.tau_rs,
        i_d_threshold: config.i_d_threshold,
        k_e0: config.k_e0,
        r_s0: config.r_s0,
    }
}

/// The observer crate's sample of `s`.
pub(super) fn sample(s: &Sample) -> greybox_observer::Sample<f64> {
    greybox_observer::Sample { i_d: s.i_d, i_q: s.i_q, u_d: s.u_d, u_q: s.u_q, w_m: s.w_m }
}

/// A setting the observer crate refused (the crate's own checks run first: not expected).
pub(crate) fn invalid(field: Field) -> Error {
    Error::InvalidOption { option: field.name().into(), reason: "out of range".into() }
}
