//! Data-side PMSM helpers shared by every PMSM model and available to user models: the
//! voltage hold, interval-mean speed, the rotation `e^{−jω_e h}` of the dq frame over a
//! period and the start-of-period voltage of a stator-held voltage (MODEL.md §4).
//!
//! Over interval k, `[t_k, t_{k+1})`, the speed is taken at its interval mean
//! `ω_m = (ω_m[k] + ω_m[k+1])/2`, so the current equation is linear and time-invariant over
//! the period and has an exact discretisation (thesis 5.2; MODEL.md §4).

pub(crate) use crate::pmsm::model::elementary::sin_cos_small;

mod dq;
mod reference;
mod source;
mod voltage;
pub use dq::{
    C64, Interval, SQRT_2_3, VoltageHold, VoltageInput, interval_mean_speed, intervals, rotation,
    stator_hold_start,
};
pub(crate) use dq::{
    SMALL_ANGLE, check_finite, check_positive, half_angle, half_angle_arg, half_angle_rotation, mean_speed,
    stator_hold_start_half,
};
pub use reference::{applied_experiment, applied_voltage, model_intervals, reference_intervals};
pub(crate) use reference::{controller_frame, driving_voltage, model_start_voltages, reference_channels};
pub(crate) use source::IntervalData;
pub use source::IntervalSource;
pub use voltage::IntervalVoltage;
pub(crate) use voltage::terminal_start;
