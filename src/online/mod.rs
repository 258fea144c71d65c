//! Online estimation of `K_e` and `R_s`, sample by sample: the model reference adaptive
//! system (MRAS) of thesis 5.1 (Tenerz 2011; MODEL.md §7), and an extended Kalman filter
//! whose covariance gives a standard error at every sample (issue 46).
//!
//! - [`MrasConfig`] (with [`Adaptation`]): known `n_p`, `l_s` (and `l_q` for a salient
//!   machine), sample time, gains;
//! - [`Mras`]: the observer, [`Mras::update`] per [`Sample`] giving [`Estimates`]; exact
//!   in the state for any sample time and implicit in the parameters (see [`Mras`]);
//! - [`InjectionSchedule`]: the periodic d-current pulse that lets `R_s` adapt;
//! - [`Kalman`] (with [`KalmanNoise`]): the filter of `(i_d, i_q, R_s, K_e)`,
//!   [`Kalman::update`] per [`Sample`] giving a [`KalmanEstimate`] (the estimates and their
//!   standard errors); [`current_noise`]: the current noise a log shows;
//! - [`track()`], [`track_kalman()`]: an observer over a whole log, a [`Trajectory`] (with
//!   the filter's standard errors; [`Trajectory::temperatures`] for the winding and magnet
//!   temperatures).
//!
//! The per-sample algorithms are the `no_std` crate `greybox-observer` (`observer/`, f32 or
//! f64, with a C ABI for drive firmware: docs/firmware.md); this module adds the salient
//! machine's exact step, the crate's errors and the runs over whole logs.
//!
//! Speeds are mechanical (`w_m` \[rad/s\]); `ω_e = n_p w_m`. Choose the voltage hold of the
//! log's source (MODEL.md §4): on a dq-held log (gym-electric-motor) the default stator
//! hold biases `K̂_e` by percents.
//!
//! # Example
//! ```
//! use greybox::online::{MrasConfig, track};
//! use greybox::pmsm::read_log;
//!
//! # fn main() -> greybox::Result<()> {
//! // The 2 s servo log shipped in the repository: 4 pole pairs, L_s = 4.5 mH known.
//! let log = read_log("data/sample.csv.gz", &Default::default())?;
//! let config = MrasConfig { n_p: 4, l_s: 4.5e-3, k_e0: 0.45, r_s0: 0.7, ..Default::default() };
//! let trajectory = track(&log, &config)?;
//! let last = trajectory.final_estimate;
//! println!("K_e = {:.4} V s/rad, K_t = {:.4} N m/A, R_s = {:.3} Ω", last.k_e, last.k_t, last.r_s);
//! let plot = trajectory.decimate(500); // at most 500 points for a figure
//! assert!(plot.t.len() <= 500);
//! # Ok(()) }
//! ```

// The submodules are the crate's; their public items are re-exported here, one path each.
pub(crate) mod config;
pub(crate) mod injection;
pub(crate) mod kalman;
pub(crate) mod mras;
#[cfg(feature = "plot")]
pub(crate) mod plot;
pub(crate) mod track;

pub use config::{Adaptation, MrasConfig};
pub use injection::InjectionSchedule;
pub use kalman::{K_E_WALK, Kalman, KalmanEstimate, KalmanNoise, MODEL_NOISE_RATIO, R_S_WALK, current_noise};
pub use mras::{Estimates, INFORMATIVE, MIN_TAU_SAMPLES, Mras, MrasOutput, Sample};
#[cfg(feature = "plot")]
pub use plot::{TrackRun, TrackTruth, track_svg};
pub use track::{
    INNOVATION_RATIO_LIMIT, TemperatureTrajectory, Trajectory, track, track_kalman, track_kalman_with,
};
