//! A closed-loop PMSM drive simulator after the thesis' servo drive (thesis ch. 4, 5.1,
//! 6.1; MODEL.md §8): the plant stepped by the offline models' exact steps
//! ([`crate::pmsm::ExactPlant`]), RK4 mechanics with friction, gravity and load, the
//! cascade controller, an averaged inverter with computational delay, angle advance and
//! dead time, sensor noise and quantisation, temperatures and parameter ramps. Logs come
//! out with the columns `greybox fit` reads (terminal and reference voltages) and a truth
//! JSON; a seed makes them reproducible.
//!
//! - [`DriveConfig`] and its parts: plain serde data, so a scenario is a JSON file;
//! - [`scenario()`]: the thesis' experiments `exp1`–`exp6` on a given motor;
//! - [`simulate_drive`] → [`DriveLog`] (an [`crate::Experiment`] and its [`Truth`]);
//! - [`DriveLog::write`]: the CSV (gzip for `.gz`) and the truth JSON, atomically.
//!
//! # Example
//! ```
//! use greybox::drive::{scenario, simulate_drive, SPM_MOTOR};
//! use greybox::pmsm::{fit_pmsm, PmsmFitOptions};
//!
//! # fn main() -> greybox::Result<()> {
//! let mut cfg = scenario("exp3", SPM_MOTOR)?;
//! cfg.duration = 1.0;
//! let log = simulate_drive(&cfg)?;
//! let options = PmsmFitOptions::new(SPM_MOTOR.n_p);
//! let fit = fit_pmsm(&[log.experiment], &options)?;
//! let r_s = fit.parameter("r_s").unwrap().value;
//! assert!((r_s / log.truth.start.r_s - 1.0).abs() < 1e-6);
//! # Ok(()) }
//! ```

// The submodules are the crate's; their public items are re-exported here, one path each.
pub(crate) mod config;
pub(crate) mod control;
pub(crate) mod design;
mod motors;
mod output;
pub(crate) mod plan;
pub(crate) mod profile;
pub(crate) mod scenario;
pub(crate) mod sim;

pub use config::{Control, DriveConfig, Inverter, Mechanics, Mode, PwmPlant, Sensors, Thermal};
pub use control::{Command, Controller, Measurement};
pub use design::{DQ_PER_PHASE_VARIANCE, PlanPrediction, predict_plan};
pub use motors::{IPM_MOTOR, IPM_SATURATION, SATURATED_IPM_MOTOR, SPM_MOTOR};
pub use plan::{Grid, Injection, Knobs, LimitUse, PLANS, planned_drive};
pub use profile::Profile;
pub use scenario::{COMMISSIONING, SCENARIOS, scenario};
pub use sim::{DriveLog, PROGRESS_EVERY, Truth, plant_at, simulate_drive, simulate_drive_with_progress};
