//! The PMSM models: the motor kinds' parameter tables, the setup, the sampled voltage and
//! its hold over an interval, the inverter, the temperatures, and the exact sampled-data
//! models [`PmsmSpm`](spm::PmsmSpm) and [`PmsmIpm`](ipm::PmsmIpm) with the plant that steps
//! them.

pub(super) mod augmented;
mod elementary;
pub(super) mod flux_map;
pub(super) mod interval;
pub(super) mod inverter;
pub(super) mod ipm;
pub(super) mod kind;
pub(super) mod mask;
pub(super) mod mechanics;
mod metadata;
pub(super) mod plant;
pub(super) mod pwm;
pub(super) mod saturated;
pub(super) mod saturation;
pub(super) mod setup;
pub(super) mod spm;
pub(super) mod standstill;
pub(super) mod temperature;
