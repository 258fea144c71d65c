//! # greybox
//!
//! Grey-box estimation of the electrical parameters of permanent-magnet synchronous
//! motors (PMSM) from drive logs: stator resistance `r_s` \[Ω\], inductance `l_s` (or `l_d`,
//! `l_q`) \[H\] and back-EMF constant `k_e` \[V s/rad\], hence torque constant `k_t` \[N m/A\]
//! and magnet flux `psi_f` \[V s\].
//!
//! Data flow: [`data`] (an [`Experiment`]: named channels read from a CSV log) →
//! [`model`] (the [`model::GreyBoxModel`] trait) → [`simulate`] (single shooting with
//! forward sensitivities, a block of [`model::BLOCK_LEN`] samples at a time; a model may
//! offer a whole-block kernel, [`model::BlockKernel`], as the surface-magnet model does) →
//! [`estimate`] (prediction-error fit by Levenberg-Marquardt or
//! Gauss-Newton, linear least squares, statistics) → [`estimate::FitResult`] (table and
//! JSON). All motor knowledge lives in [`pmsm`]: the dq view of a log, the exact
//! [`pmsm::PmsmSpm`] and [`pmsm::PmsmIpm`] models, the least-squares start, and
//! [`pmsm::fit_pmsm`], which does it all in one call. Physics and conventions: Tenerz (2011), *Parameter estimation in a
//! permanent magnet synchronous motor*, chapters 3 and 5; dq quantities are
//! amplitude-invariant, speeds and angles mechanical unless a name says `_e`.
//!
//! [`online`] estimates `k_e` and `r_s` sample by sample with the MRAS observer of thesis
//! 5.1 ([`online::Mras`]; a whole log with [`online::track()`]).
//! [`drive`] simulates a closed-loop servo drive (thesis ch. 4; scenarios exp1–exp6) whose
//! logs the offline models reproduce exactly.
//!
//! # Example
//! ```
//! use greybox::pmsm::{fit_pmsm, read_log, PmsmFitOptions};
//!
//! # fn main() -> greybox::Result<()> {
//! // A 2 s log of a servo motor with 4 pole pairs, shipped in the repository.
//! let log = read_log("data/sample.csv.gz", &Default::default())?;
//! let fit = fit_pmsm(&[log], &PmsmFitOptions::new(4))?;
//! assert!(fit.solver.success);
//! let r_s = fit.parameter("r_s").unwrap();
//! println!("R_s = {:.6} ± {:.1e} Ω", r_s.value, r_s.std_error);
//! println!("{fit}");
//! # Ok(()) }
//! ```
#![warn(missing_docs)]
// Units are written in brackets, `[V]`, `[rad/s]`, as in the field's texts; rustdoc would
// read them as links.

pub mod app;
/// The command-line tool's modules (feature `cli`): flags, commands, report files; the
/// `greybox` binary is thin over them (the fits through [`app`]), and so are the Python
/// package's tools other than the fits.
#[cfg(feature = "cli")]
pub mod cli;
pub mod data;
pub mod drive;
mod error;
pub mod estimate;
pub mod model;
pub mod online;
pub mod pmsm;
pub mod prelude;
pub mod report;
pub mod simulate;

pub use data::{Channel, Experiment};
pub use error::{Error, Result};

/// The README's code examples, compiled as doctests so that they stay true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
