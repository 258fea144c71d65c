//! The thresholds, ratios and search ranges the PMSM fits decide by: when a check speaks
//! (a loss so many times lower at another pole-pair number, delay or column reading), which
//! hold or model a fit keeps, and over which range a search runs. They are tuning, not
//! physics: each is documented where it is used, with the measurement that set it, and is
//! public so that a report's wording ("10 times lower") can be traced to its value.
//!
//! The physical constants, channel names and the reader's limits stay in [`crate::pmsm`]
//! itself ([`crate::pmsm::ALPHA_COPPER`], [`crate::pmsm::MAX_POLE_PAIRS`], …).

pub use super::checks::advice::{LATE_SLOPE, THRESHOLD as LATE_VOLTAGE_THRESHOLD};
pub use super::checks::columns::COLUMN_RATIO;
pub use super::checks::delay::{DELAY_RATIO, PWM_DELAY_SAMPLES};
pub use super::checks::detect::{MAX_H_OVER_TAU, SALIENCY, SALIENT_CERTAIN, SALIENT_LIKELY, SPEED_MISMATCH};
pub use super::checks::noise::{NEGLIGIBLE_VOLTAGE_NOISE, NOISE_SIGNIFICANCE_Z};
pub use super::checks::pole_pairs::{POLE_PAIR_CANDIDATES, POLE_PAIR_RATIO, POLE_PAIR_Z};
pub use super::fit::auto_mask::FALLBACK_RELATIVE_THRESHOLD;
pub use super::fit::flux_map::FLUX_MAP_REFINED;
pub use super::fit::flux_map_check::{INDUCTANCE_WITHIN, NO_LOAD_WITHIN};
pub use super::fit::flux_map_regions::REGION_POINTS;
pub use super::fit::hold::{DQ_DECISIVE, HOLD_AMBIGUOUS_Z, HOLD_TIE_Z, SCREEN_DECISIVE};
pub use super::fit::input_search::{ADVANCE_RANGE, DELAYS};
pub use super::fit::iv::{IV_MAX_ITERATIONS, IV_STEP_TOLERANCE};
pub use super::fit::late_voltage::LATE_Z;
pub use super::fit::mechanics::{COULOMB_SPEED_RANGE, MIN_WINDOWS};
pub use super::fit::pole_pairs::AUTO_CANDIDATES;
pub use super::fit::saturated::LOCAL_MINIMUM_EXCESS;
pub use super::fit::search::SPEED_PLL_RANGE;
pub use super::fit::standstill::{STANDSTILL_PART_SAMPLES, STANDSTILL_PARTS, UNEXCITED_AXIS};
pub use super::fit::steady_trust::{STEADY_MIN_DOF, STEADY_PRECISION};
pub use super::linear::STEADY_UNIDENTIFIABLE;
pub use super::linear::report::LS_BIAS_UNTRUSTED;
pub use super::model::inverter::DEFAULT_RELATIVE_WIDTH;
pub use super::model::saturated::SATURATED_SUBSTEP_RHO;
