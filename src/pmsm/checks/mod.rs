//! The checks of a log and its fit that name a setup mistake: the setup scan's regression
//! Gram, the pole-pair number, the detectors (saliency, speed unit and frame, sample time), column
//! mistakes, the reference voltage's delay, the inverter's dead time and a late voltage,
//! the voltage limit, a point-sampled voltage, voltage noise, its bias of an output-error
//! fit and the noise floor it leaves, the current noise's bias of a masked fit, and whether
//! the log's parts agree (the inverter model's error).

pub(super) mod advice;
pub(super) mod columns;
pub(super) mod delay;
pub(super) mod detect;
pub(super) mod limit;
pub(super) mod noise;
pub(super) mod noise_bias;
pub(super) mod noise_floor;
pub(super) mod pole_pairs;
pub(super) mod prepared;
pub(super) mod sampling;
pub(super) mod scan;
pub(super) mod segments;
pub(super) mod time_unit;
pub(super) mod voltage_bias;
