//! The names most programs use, in one import: `use greybox::prelude::*;`. Reading a log,
//! fitting a motor (from the measured or the reference voltage), the fit's result and its
//! options, the drive simulator, the mechanics and the online observer; everything else
//! under its folder ([`crate::pmsm`], [`crate::estimate`], …).

pub use crate::data::{ColumnMap, CsvSpec, read_csv};
pub use crate::drive::{DriveConfig, IPM_MOTOR, SPM_MOTOR, scenario, simulate_drive};
pub use crate::estimate::{FitResult, PemOptions, SpeedShape, Warning, WeightingKind};
pub use crate::online::{MrasConfig, track};
pub use crate::pmsm::{
    CsvOptions, HoldChoice, InputSearch, MechanicsOptions, MotorKind, PmsmFit, PmsmFitOptions, VoltageInput,
    fit_estimating_input, fit_mechanics, fit_pmsm, read_log,
};
// Not `greybox::Result`: a glob import of it would shadow the standard `Result<T, E>`.
pub use crate::{Channel, Error, Experiment};
