//! The online estimators of `greybox`, for drive firmware: the thesis' MRAS observer of
//! `K_e` and `R_s` ([`Mras`]; Tenerz 2011, 5.1) and the extended Kalman filter of
//! `(i_d, i_q, R_s, K_e)` with a standard error at every sample ([`Kalman`]; Simon 2006,
//! §13.2), one sample at a time.
//!
//! `#![no_std]`, no allocation, no panic, in `f32` or `f64` ([`Real`]); the elementary
//! functions come from the `libm` crate (or, with the feature `std`, from the host's C
//! library: then the `f64` estimates are those of `greybox track` to the bit, which uses
//! this crate). The C ABI and its header are the crate `greybox-observer-capi`.
//!
//! - [`Settings`]: the machine (`n_p`, `l_s`, `h`, the voltage's [`Hold`]) and the MRAS's
//!   gains ([`Adaptation`]); [`Noise`]: the filter's noise model.
//! - [`Sample`] in (currents at `t_k`, the period's mean voltage and speed), [`Estimates`]
//!   out (`K_e`, `K_t`, `ψ_f`, `R_s`, the error, standard errors), [`Fault`] on failure.
//! - [`Plant`]: the exact one-period step the observers follow; [`Spm`] in closed form,
//!   [`Ipm`] (a salient machine, `L_d ≠ L_q`) by its augmented exponential; [`Machine`]
//!   chooses between them.
//!
//! Speeds are mechanical (`w_m` \[rad/s\]), `ω_e = n_p w_m`; currents and voltages peak dq
//! (MODEL.md §2).
//!
//! # Example
//! ```
//! use greybox_observer::{Kalman, Noise, Sample, Settings};
//!
//! let mut s = Settings::new(4, 4.5e-3_f32, 1e-4);
//! (s.k_e0, s.r_s0) = (0.4, 0.5);
//! let mut ekf = Kalman::spm(s, Noise::for_machine(0.01, s.r_s0, s.k_e0)).unwrap();
//! let e = ekf.update(&Sample { i_d: 0.0, i_q: 2.0, u_d: -1.0, u_q: 15.0, w_m: 30.0 }).unwrap();
//! assert_eq!(e.k_e, 0.4);
//! assert!(e.k_e_se > 0.0);
//! ```
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod kalman;
mod machine;
mod mras;
mod plant;
mod real;
mod salient;
mod series;
mod types;

pub use kalman::{K_E_WALK, Kalman, MODEL_NOISE_RATIO, Noise, R_S_WALK};
pub use machine::Machine;
pub use mras::{INFORMATIVE, Mras, MrasOutput};
pub use num_complex::Complex;
pub use plant::{Plant, Spm, Step, Transition, phi1, phi1_pair, phi1_pair_real, phi1_prime};
pub use real::{Real, SQRT_2_3, cexpm1, rotation, stator_hold_start, stator_hold_start_sin};
pub use salient::{Ipm, StepError};
pub use series::{
    Aug, Coefficients, MAX_SUBSTEPS, RHO_MAX, SENS_ALL, SENS_NONE, SENS_R_K, Substep, advance_substeps,
    advance_substeps_transition,
};
pub use types::{Adaptation, Estimates, Fault, Field, Hold, MIN_TAU_SAMPLES, Sample, Settings};
