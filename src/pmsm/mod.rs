//! Everything the library knows about permanent-magnet synchronous motors, behind one
//! public face: the items below are the whole API; the modules are private but [`thresholds`].
//!
//! Inside, in dependency order (each layer uses only the ones before it):
//! - `log`: the reader for drive logs ([`read_log`]: units, frames, dq from phases), the
//!   typed [`DqView`] of the channels, Clarke and Park;
//! - `model`: the motor kinds' parameter tables ([`MotorKind`]), the setup, the voltage
//!   over an interval ([`VoltageHold`], [`VoltageInput`]), the inverter, temperatures, and
//!   the exact sampled-data models [`PmsmSpm`], [`PmsmIpm`] with the plant that steps them;
//! - `options`: [`PmsmFitOptions`], the one struct every step of a fit reads;
//! - `linear`: the least-squares estimate on the voltage equations ([`least_squares`]) and
//!   the fit's start;
//! - `checks`: the setup scan and the detectors that name a setup mistake;
//! - `fit`: the workflow [`fit_pmsm`] and what builds on it ([`fit_estimating_input`],
//!   [`fit_pmsm_iv`], [`choose_pole_pairs_by_fit`]), the report [`PmsmFit`], validation;
//! - [`thresholds`], the one public module: the ratios, thresholds and search ranges the
//!   fits decide by, out of this face.
//!
//! Physics and conventions: Tenerz (2011), *Parameter estimation in a permanent magnet
//! synchronous motor*, chapters 3 and 5; MODEL.md (`docs/model.md`). dq quantities are
//! amplitude-invariant, speeds and angles mechanical unless a name says `_e`.

mod checks;
mod fit;
mod linear;
mod log;
mod model;
mod options;
pub mod thresholds;

pub use checks::limit::VoltageLimitWeighting;
pub use checks::pole_pairs::{choose_pole_pairs, pole_pair_losses};
pub use fit::auto_method::fit_pmsm_by;
pub use fit::flux_map::{ExponentCandidate, FluxMapFit, FluxMapOptions, fit_flux_map};
pub use fit::flux_map_check::{MapCheck, MapModel, PointCheck};
pub use fit::flux_map_regions::{RegionCheck, Widened};
pub use fit::flux_map_torque::{TorqueCheck, torque_check};
pub use fit::input_search::{InputSearch, fit_estimating_input};
pub use fit::iv::{Estimator, check_options as check_iv_options, fit_pmsm_iv, fit_pmsm_iv_after};
pub use fit::mechanics::{LOAD_TORQUE, MechanicsFit, MechanicsOptions, fit_mechanics, mechanics_windows};
pub use fit::pole_pairs::{AutoPolePairs, choose_pole_pairs_by_fit};
pub use fit::report::{PmsmFit, ReportOptions, StartComparison, conventions, estimate_table};
pub use fit::saturated::{SaturatedFit, fit_saturated};
pub use fit::standstill::{STANDSTILL_T0, StandstillFit, StandstillOptions, fit_standstill};
pub use fit::validate::SavedModel;
pub use fit::workflow::fit_pmsm;
pub use linear::{
    LinearEstimate, LinearOptions, PERIOD_TERM, SteadyEstimate, SteadyOptions, least_squares, regressors,
    steady_advice, steady_state, weighted_least_squares,
};
pub use log::flux_map::{
    FluxMapColumns, FluxMapRead, NPZ_ARRAYS, read_flux_map, read_flux_map_from, read_flux_map_with,
};
pub use log::signals::{DqSignals, DqView, MAX_POLE_PAIRS, MIN_SAMPLES, PmsmError, channel};
pub use log::transform::{
    clarke, currents_to_dq, inverse_clarke, inverse_park, park, stator_held_voltages_to_dq,
    stator_hold_mean_factor,
};
pub use log::{
    AngleUnit, ColumnNames, CsvOptions, DqSource, DroppedSegment, Frame, LogSegments, LogSource,
    MAX_SAMPLE_TIME, MAX_STEADY_SAMPLE_TIME, MIN_SAMPLE_TIME, Scale, SpeedUnit, TimeUnit, read_log,
    read_log_from, read_log_segments, read_log_segments_from, read_logs,
};
pub use model::flux_map::{FLUX_MAP_CHANNELS, FluxMapModel};
pub use model::interval::{
    C64, Interval, IntervalSource, IntervalVoltage, SQRT_2_3, VoltageHold, VoltageInput, applied_experiment,
    applied_voltage, interval_mean_speed, intervals, model_intervals, reference_intervals, rotation,
    stator_hold_start,
};
pub use model::inverter::{InverterModel, dead_time_directions};
pub use model::ipm::PmsmIpm;
pub use model::kind::{MotorKind, derived};
pub use model::mask::{DeadTimeMask, DeadTimeMaskWeighting};
pub use model::mechanics::{Axis, MECHANICS_CHANNELS, MechanicsInputs, MechanicsModel, MechanicsTerms};
pub use model::plant::{ExactPlant, MotorParameters, StepDerivatives};
pub(crate) use model::pwm::PwmPlantStep;
pub use model::pwm::{
    CarrierEdge, Modulator, PmsmPwm, PwmCoefficients, PwmInputs, PwmInverter, PwmUpdate, SignMargin,
};
pub use model::saturated::{PmsmSaturated, SaturatedCoefficients, saturated_step, saturated_substeps};
pub use model::saturation::{
    CurrentDerivatives, Inductances, SATURATION_PARAMETERS, Saturation, SaturationExponents,
};
pub use model::setup::PmsmSetup;
pub use model::spm::{PmsmSpm, SpmInputs};
pub use model::standstill::{
    StandstillCoefficients, StandstillInputs, StandstillModel, StandstillSetup, WINDING_TEMPERATURE,
};
pub use model::temperature::{ALPHA_COPPER, BETA_NDFEB, ThermalReference};
pub use options::{Dynamics, HoldChoice, PmsmFitOptions};
