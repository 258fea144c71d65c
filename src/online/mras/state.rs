//! The observer's data: a sample in, the estimates out, and the observer's state.

#[cfg(doc)]
use super::super::config::Adaptation;
use super::super::config::MrasConfig;
use crate::pmsm::{C64, ExactPlant};
use serde::{Deserialize, Serialize};

/// One sample of a drive: the currents measured at `t_k` and the voltage applied over
/// the coming period `[t_k, t_k + h)` (MODEL.md §4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// d-axis current at `t_k` \[A, peak dq\].
    pub i_d: f64,
    /// q-axis current at `t_k` \[A, peak dq\].
    pub i_q: f64,
    /// d-axis voltage over `[t_k, t_k + h)` \[V\], its period mean.
    pub u_d: f64,
    /// q-axis voltage over `[t_k, t_k + h)` \[V\], its period mean.
    pub u_q: f64,
    /// Mechanical speed over the coming period \[rad/s\] (the interval mean
    /// `(ω_m[k] + ω_m[k+1])/2` when known, as [`crate::online::track()`] passes it; else ω_m\[k\]).
    pub w_m: f64,
}

/// What the observer knows after a sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Estimates {
    /// Back-EMF constant K̂_e \[V s/rad\] (line-to-line RMS per mechanical rad/s).
    pub k_e: f64,
    /// Torque constant `K̂_t = √(3/2) K̂_e` \[N m/A, peak dq current\] (MODEL.md §2).
    pub k_t: f64,
    /// Magnet flux linkage `ψ̂_f = √(2/3) K̂_e / n_p` \[V s\] (MODEL.md §2).
    pub psi_f: f64,
    /// Stator resistance R̂_s \[Ω\].
    pub r_s: f64,
    /// d-axis observer error `i_d − î_d` at `t_k` before adaptation \[A\].
    pub e_d: f64,
    /// q-axis observer error `i_q − î_q` at `t_k` before adaptation \[A\].
    pub e_q: f64,
    /// Whether `R̂_s` adapted at this sample (see [`MrasConfig::r_s_adapts`]).
    pub r_s_active: bool,
}

/// What [`Mras::compute_output`] found for one sample: the estimates, and the
/// observer's next state for [`Mras::advance`].
#[derive(Clone, Copy, Debug)]
pub struct MrasOutput {
    /// The estimates after the adaptation at `t_k`.
    pub estimates: Estimates,
    /// Index of the sample this output belongs to.
    pub(super) sample: usize,
    pub(super) next: Next,
}

/// The observer's state after a sample.
#[derive(Clone, Copy, Debug)]
pub(super) struct Next {
    pub(super) i_hat: C64,
    pub(super) phi_k: C64,
    pub(super) phi_r: C64,
    pub(super) psi_k: C64,
    pub(super) k_e: f64,
    pub(super) r_s: f64,
    pub(super) p_k: f64,
    pub(super) p_r: f64,
}

/// The MRAS observer (thesis 5.1): state `î` and parameters `(K̂_e, R̂_s)`; see the module
/// documentation for the design and the discretisation.
///
/// [`Mras::update`] takes a [`Sample`], corrects and adapts at `t_k`, and propagates the
/// observer to `t_{k+1}`. It is split as motulator's observers are: [`Mras::compute_output`]
/// (`&self`: the estimates and the next state) and [`Mras::advance`] (commits them), so a
/// controller can use the estimates before the state moves. [`Mras::output`] repeats the
/// last estimates. No allocation, no panic.
#[derive(Clone, Debug)]
pub struct Mras {
    pub(super) cfg: MrasConfig,
    /// `1 − e^{−f h}`: the share of the error the observer takes per period.
    pub(super) kappa: f64,
    pub(super) k_e: f64,
    pub(super) r_s: f64,
    /// Observer prediction of the current at the next sample \[A\].
    pub(super) i_hat: C64,
    /// Sensitivities of `i_hat` to K̂_e and R̂_s over the last step, and the K_e law's
    /// direction (φ_K, or φ_K/|ω_m| for the relay).
    pub(super) phi_k: C64,
    pub(super) phi_r: C64,
    pub(super) psi_k: C64,
    /// Mean information `|φ|²` of K̂_e and R̂_s over the last τ ([`Adaptation::Normalised`];
    /// 0 before any).
    pub(super) p_k: f64,
    pub(super) p_r: f64,
    /// Samples consumed; 0 means the observer starts at the next measurement.
    pub(super) n: usize,
    pub(super) last: Estimates,
    /// The salient step (`Some` when [`MrasConfig::salient`]).
    pub(super) plant: Option<ExactPlant>,
}

/// Share of the mean information below which a sample does not update it
/// ([`Adaptation::Normalised`]).
pub const INFORMATIVE: f64 = 0.1;

/// Shortest time constant of [`Adaptation::Normalised`], in sample times: measured on a
/// 10 kHz log with 1 V of voltage noise, 20 samples diverged and 30 did not; the margin
/// keeps the adaptation well slower than the observer's error dynamics.
pub const MIN_TAU_SAMPLES: f64 = 100.0;
