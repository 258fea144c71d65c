//! The PMSM fit: the workflow [`fit_pmsm`](workflow::fit_pmsm) and what builds on it
//! (the voltage input's search, instrumental variables, the automatic pole pairs), the
//! hold choice, the report, and a saved fit's validation and simulation.

pub(super) mod angle_offset;
pub(super) mod auto_mask;
pub(super) mod auto_method;
mod base;
mod beside;
pub(super) mod current_offset;
pub(super) mod flux_map;
pub(super) mod flux_map_check;
mod flux_map_grid;
pub(super) mod flux_map_regions;
pub(super) mod flux_map_torque;
mod friction;
pub(super) mod hold;
mod holds;
pub(super) mod input_search;
pub(super) mod iv;
mod iv_report;
pub(super) mod late_voltage;
pub(super) mod mechanics;
mod mechanics_report;
pub(super) mod pole_pairs;
mod pwm_fit;
mod pwm_leg_state;
mod pwm_loop;
mod pwm_mask;
mod pwm_noise;
mod pwm_start;
pub(super) mod report;
pub(super) mod saturated;
pub(super) mod search;
pub(super) mod simulated;
pub(super) mod standstill;
pub(super) mod steady;
mod steady_agreement;
mod steady_checks;
mod steady_report;
pub(super) mod steady_trust;
pub(super) mod validate;
pub(super) mod workflow;
