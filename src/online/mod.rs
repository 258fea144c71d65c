//! Online estimation of `K_e` and `R_s`, sample by sample: the model reference adaptive
//! system (MRAS) of thesis 5.1 (Tenerz 2011; MODEL.md §7).
//!
//! - [`MrasConfig`] (with [`Adaptation`]): known `n_p`, `l_s`, sample time, gains;
//! - [`Mras`]: the observer, [`Mras::update`] per [`Sample`] giving [`Estimates`]; exact
//!   in the state for any sample time and implicit in the parameters (see [`mras`]);
//! - [`InjectionSchedule`]: the periodic d-current pulse that lets `R_s` adapt;
//! - [`track`]: the observer over a whole log, a [`Trajectory`].
//!
//! Speeds are mechanical (`w_m` [rad/s]); `ω_e = n_p w_m`.

pub mod config;
pub mod injection;
pub mod mras;
pub mod track;

pub use config::{Adaptation, MrasConfig};
pub use injection::InjectionSchedule;
pub use mras::{Estimates, Mras, MrasOutput, Sample};
pub use track::{Trajectory, track};
