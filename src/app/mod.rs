//! The application layer: what a user asks of the library (a fit of logs, a batch of
//! them), typed and without a command line. The command line converts its flags into
//! these requests, the Python package its keywords; both run them through the functions
//! here, so that defaults, checks and results are the same to the bit.
//!
//! - [`FitRequest`]: the options of a fit; [`plan`] turns it into the library's options
//!   ([`Plan`]) before any log is read, refusing what the fit cannot honour.
//! - [`read_sources`], [`read_logs`]: the logs as asked ([`LogReading`]); [`fit_experiments`]
//!   fits them ([`Fitted`]: the JSON report, its table, the fit).
//! - [`fit_each`]: many logs, each on its own, one summary [`Record`] per log.
//! - [`TrackRequest`]: the options of an online estimation; [`track_logs`] runs it.
//! - [`ValidateRequest`]: a saved fit against other logs; [`validate`] compares them.
//! - [`SimulateRequest`]: a simulated drive log; [`drive_config`] builds its configuration.
//! - [`FluxMapRequest`], [`SaturationRequest`], [`StandstillRequest`], [`MechanicsRequest`]:
//!   the fits of issue 33; [`fluxmap`], [`saturation`], [`standstill`], [`mechanics`] run
//!   them into a [`Report`].
//! - [`Choice`] and the values of [`values`]: the words both front ends accept.
//!
//! No item here prints, exits or draws a progress bar: the front ends do.

mod batch;
mod choice;
pub mod columns;
mod fitted;
mod logs;
mod plan;
#[cfg(feature = "plot")]
pub mod plots;
mod reading;
mod reports;
mod request;
mod simulate;
mod track;
mod validate;
pub mod values;
pub mod words;

pub use batch::summary::{self, Cell, Record, Status};
pub use batch::{LOG_ENDINGS, batch_plan, expand, fit_each, stem};
pub use choice::Choice;
pub use fitted::{FitOutcome, Fitted, fit_experiments};
pub use logs::{check_paths, unique_names};
pub use plan::{Plan, fit_logs, plan, pole_pairs};
pub use reading::{named, read_logs, read_segments_from, read_sources};
pub use reports::{
    FluxMapRequest, MechanicsRequest, Report, SaturationRequest, StandstillRequest, exponents, fluxmap,
    mechanics, saturation, standstill,
};
pub use request::{FitRequest, LogReading, PwmRequest};
pub use simulate::{Motor, SimulateRequest, drive_config, set_field};
pub use track::{Estimator, KalmanSettings, MrasSettings, TrackRequest, TrackedLog, track_logs};
pub use validate::{ValidateRequest, validate, validation_json};
pub use values::{
    Advance, DeadTime, Delay, Gain, InverterChoice, LegWidth, Method, ModelChoice, Pll, PolePairs, Voltage,
};
