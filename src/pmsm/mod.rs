//! Everything the library knows about permanent-magnet synchronous motors, in one place.
//!
//! - [`signals`]: the PMSM channels of a log and the typed [`DqView`];
//! - [`log`]: the CSV reader for drive logs (units, frames, dq from phases);
//! - [`transform`]: Clarke and Park;
//! - [`interval`]: voltage hold, interval-mean speed, rotation, stator-hold voltage;
//! - [`kind`]: the parameter table per motor kind (names, units, advice, derived);
//! - [`spm`], [`ipm`] (with the [`augmented`] exponential): the exact sampled-data models;
//! - [`linear`]: the least-squares start on the voltage equations;
//! - [`fit`]: the whole workflow in one call, [`fit_pmsm`].
//!
//! Physics and conventions: Tenerz (2011), *Parameter estimation in a permanent magnet
//! synchronous motor*, chapters 3 and 5; MODEL.md. dq quantities are amplitude-invariant,
//! speeds and angles mechanical unless a name says `_e`.

pub mod augmented;
pub mod fit;
pub mod interval;
pub mod ipm;
pub mod kind;
pub mod linear;
pub mod linear_report;
pub mod log;
pub mod signals;
pub mod spm;
pub mod transform;
pub mod validate;

pub use fit::{HoldChoice, PmsmFit, PmsmFitOptions, fit_pmsm};
pub use interval::{
    C64, Interval, SQRT_2_3, VoltageHold, interval_mean_speed, intervals, rotation, stator_hold_start,
};
pub use ipm::PmsmIpm;
pub use kind::{MotorKind, derived};
pub use linear::{LinearEstimate, LinearOptions, least_squares, regressors, weighted_least_squares};
pub use log::{AngleUnit, ColumnNames, CsvOptions, DqSource, Frame, Scale, SpeedUnit, read_log, read_logs};
pub use signals::{DqSignals, DqView, MIN_SAMPLES, channel};
pub use spm::PmsmSpm;
pub use validate::SavedModel;

use crate::model::Signal;

/// The outputs of every PMSM model: the dq currents `id`, `iq` [A].
pub(crate) fn current_outputs() -> Vec<Signal> {
    vec![Signal::new(channel::I_D, "A"), Signal::new(channel::I_Q, "A")]
}
