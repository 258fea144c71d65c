//! The observer's data: the estimates out and the observer's state (a sample in:
//! [`super::sample`]).

#[cfg(doc)]
use super::super::config::Adaptation;
use super::super::config::MrasConfig;
use super::step::Machine;
use serde::{Deserialize, Serialize};

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
    pub(super) inner: greybox_observer::MrasOutput<f64>,
}

/// The MRAS observer (thesis 5.1): state `î` and parameters `(K̂_e, R̂_s)`; see the module
/// documentation for the design and the discretisation.
///
/// [`Mras::update`] takes a [`Sample`](super::sample::Sample), corrects and adapts at `t_k`, and propagates the
/// observer to `t_{k+1}`. It is split as motulator's observers are: [`Mras::compute_output`]
/// (`&self`: the estimates and the next state) and [`Mras::advance`] (commits them), so a
/// controller can use the estimates before the state moves. [`Mras::output`] repeats the
/// last estimates. No allocation, no panic. The observer itself is
/// [`greybox_observer::Mras`] (`no_std`, for firmware), here with the salient step too.
#[derive(Clone, Debug)]
pub struct Mras {
    pub(super) core: greybox_observer::Mras<f64, Machine>,
    pub(super) cfg: MrasConfig,
}

/// Share of the mean information below which a sample does not update it
/// ([`Adaptation::Normalised`]).
pub const INFORMATIVE: f64 = greybox_observer::INFORMATIVE;

/// Shortest time constant of [`Adaptation::Normalised`], in sample times: measured on a
/// 10 kHz log with 1 V of voltage noise, 20 samples diverged and 30 did not; the margin
/// keeps the adaptation well slower than the observer's error dynamics.
pub const MIN_TAU_SAMPLES: f64 = greybox_observer::MIN_TAU_SAMPLES;

/// The crate's estimates of the observer's (without standard errors).
pub(crate) fn estimates(e: &greybox_observer::Estimates<f64>) -> Estimates {
    Estimates {
        k_e: e.k_e,
        k_t: e.k_t,
        psi_f: e.psi_f,
        r_s: e.r_s,
        e_d: e.e_d,
        e_q: e.e_q,
        r_s_active: e.r_s_active,
    }
}
