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
pub mod checks;
mod columns;
pub mod detect;
mod elementary;
pub mod fit;
pub mod hold;
pub mod input_search;
pub mod interval;
pub mod inverter;
pub mod ipm;
pub mod iv;
pub mod kind;
pub mod limit;
pub mod linear;
pub mod linear_report;
pub mod log;
pub mod mask;
mod noise;
pub mod plant;
pub mod report;
mod scan;
pub mod setup;
pub mod signals;
pub mod simulated;
pub mod spm;
pub(crate) mod start;
pub mod temperature;
pub mod transform;
pub mod validate;

pub use fit::{HoldChoice, PmsmFit, PmsmFitOptions, StartComparison, fit_pmsm};
pub use input_search::{InputSearch, fit_estimating_input};
pub use interval::{
    C64, Interval, IntervalSource, IntervalVoltage, SQRT_2_3, VoltageHold, VoltageInput, applied_experiment,
    applied_voltage, interval_mean_speed, intervals, model_intervals, reference_intervals, rotation,
    stator_hold_start,
};
pub use inverter::InverterModel;
pub use ipm::PmsmIpm;
pub use iv::{Estimator, fit_pmsm_iv};
pub use kind::{MotorKind, derived};
pub use linear::{LinearEstimate, LinearOptions, least_squares, regressors, weighted_least_squares};
pub use log::{
    AngleUnit, ColumnNames, CsvOptions, DqSource, DroppedSegment, Frame, LogSegments, Scale, SpeedUnit,
    TimeUnit, read_log, read_log_segments, read_logs,
};
pub use mask::{DeadTimeMask, DeadTimeMaskWeighting};
pub use plant::{ExactPlant, MotorParameters, StepDerivatives};
pub use report::ReportOptions;
pub use setup::PmsmSetup;
pub use signals::{DqSignals, DqView, MIN_SAMPLES, channel};
pub use spm::PmsmSpm;
pub use temperature::{ALPHA_COPPER, BETA_NDFEB, ThermalReference};
pub use validate::SavedModel;

/// The part of [`crate::model::GreyBoxModel`] every PMSM model shares, from its motor
/// kind's table: name, the dq current state and outputs `id`, `iq` \[A\], the channels read
/// (`ud`, `uq`, `w_m`), parameter metadata (`self.params`), advice, and `k_t`, `psi_f`
/// derived with `self.n_p` pole pairs.
macro_rules! pmsm_model_metadata {
    ($kind:expr) => {
        fn name(&self) -> &str {
            $kind.model_name()
        }
        fn n_states(&self) -> usize {
            2
        }
        fn outputs(&self) -> Vec<$crate::model::Signal> {
            use $crate::pmsm::channel;
            vec![$crate::model::Signal::new(channel::I_D, "A"), $crate::model::Signal::new(channel::I_Q, "A")]
        }
        fn input_channels(&self) -> Vec<String> {
            use $crate::pmsm::channel;
            [channel::U_D, channel::U_Q, channel::W_M].map(String::from).to_vec()
        }
        fn parameters(&self) -> &[$crate::model::Parameter] {
            &self.params
        }
        fn advice(&self, name: &str) -> Option<String> {
            $kind.advice(name)
        }
        fn pair_advice(&self, a: &str, b: &str) -> Option<String> {
            $kind.pair_advice(a, b)
        }
        fn poor_fit_advice(&self) -> Option<String> {
            Some($crate::pmsm::kind::POOR_FIT_ADVICE.into())
        }
        fn implausible(&self, theta: &[f64]) -> Vec<String> {
            $kind.implausible(theta)
        }
        fn derived(&self, theta: &[f64], covariance: &[Vec<f64>]) -> Vec<$crate::model::DerivedEstimate> {
            let se: Vec<f64> = (0..theta.len()).map(|j| covariance[j][j].sqrt()).collect();
            let mut d = $crate::pmsm::kind::derived($kind, self.setup.n_p, theta, &se);
            let psi = d.iter().find(|q| q.name == "psi_f").map(|q| (q.value, q.std_error));
            if let (Some(t), Some((psi_f, se_psi))) = (&self.setup.thermal, psi) {
                d.extend(t.temperatures(theta[0], se[0], psi_f, se_psi));
            }
            d
        }
    };
}
pub(crate) use pmsm_model_metadata;
