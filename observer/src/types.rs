//! What goes into an observer and what comes out: the settings, a sample, the estimates and
//! the faults. `#[repr(C)]`, so that the C ABI (`greybox-observer-capi`) passes them as they
//! are.

use crate::real::{Real, SQRT_2_3};

/// How the voltage is held between samples (MODEL.md §4).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Hold {
    /// `u_dq` constant over `[t_k, t_k + h)` (some simulators).
    Dq = 0,
    /// `u_αβ` constant over the period (an inverter); `u[k]` is the period mean of the
    /// rotating dq voltage.
    #[default]
    Stator = 1,
}

/// The MRAS's adaptation laws (thesis 5.1; `greybox::online::Adaptation`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Adaptation {
    /// The thesis' Lyapunov law `dK̂_e/dt = γ_Ke Dᵀ e` (eq. 5.3), fixed gains.
    #[default]
    Lyapunov = 0,
    /// The relay law: the back-EMF direction without the speed's magnitude.
    Relay = 1,
    /// Gains normalised by the mean information over `tau_ke`, `tau_rs`.
    Normalised = 2,
}

/// The settings of an observer of a surface-magnet machine (and the gains of the MRAS).
/// Units: SI; the defaults of [`Settings::new`] are `greybox::online::MrasConfig`'s.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings<T> {
    /// Pole pairs `n_p`, at least 1.
    pub n_p: u32,
    /// How the voltage is held over a period.
    pub hold: Hold,
    /// The MRAS's adaptation law (not used by the Kalman filter).
    pub adaptation: Adaptation,
    /// Stator inductance `L_s` \[H\] (`L_d` for a salient machine), positive.
    pub l_s: T,
    /// Sample time `h` \[s\], positive.
    pub h: T,
    /// Observer feedback `f` \[1/s\] (`F = diag(f, f)`), at least 0. Default 100.
    pub f: T,
    /// `γ_Ke` \[(V s/rad)/(A s)\], at least 0. Default 0.001 (thesis 5.1).
    pub gamma_ke: T,
    /// `γ_Rs` \[Ω/(A s)\], at most 0 (thesis sign). Default −10 (thesis eq. 5.4).
    pub gamma_rs: T,
    /// `τ_Ke` \[s\] of [`Adaptation::Normalised`], positive. Default 0.5.
    pub tau_ke: T,
    /// `τ_Rs` \[s\] of [`Adaptation::Normalised`], positive. Default 0.5.
    pub tau_rs: T,
    /// `R_s` adapts only while `|i_d|` exceeds this \[A\], at least 0. Default 0.5.
    pub i_d_threshold: T,
    /// Initial `K_e` \[V s/rad\], finite.
    pub k_e0: T,
    /// Initial `R_s` \[Ω\], at least 0.
    pub r_s0: T,
}

impl<T: Real> Settings<T> {
    /// The defaults (`greybox::online::MrasConfig`'s; `greybox track` takes
    /// [`Adaptation::Normalised`]) for a machine of `n_p` pole pairs, inductance
    /// `l_s` \[H\] and sample time `h` \[s\], started at `K_e = R_s = 0`, stator hold.
    pub fn new(n_p: u32, l_s: T, h: T) -> Self {
        Self {
            n_p,
            hold: Hold::Stator,
            adaptation: Adaptation::Lyapunov,
            l_s,
            h,
            f: T::c(100.0),
            gamma_ke: T::c(0.001),
            gamma_rs: T::c(-10.0),
            tau_ke: T::c(0.5),
            tau_rs: T::c(0.5),
            i_d_threshold: T::c(0.5),
            k_e0: T::zero(),
            r_s0: T::zero(),
        }
    }

    /// The first field out of range, if any (see each field; `tau_ke` and `tau_rs` must
    /// also be at least [`MIN_TAU_SAMPLES`] sample times under [`Adaptation::Normalised`]).
    pub fn invalid(&self) -> Option<Field> {
        let pos = |v: T| v.is_finite() && v > T::zero();
        let nonneg = |v: T| v.is_finite() && v >= T::zero();
        let min_tau = T::c(MIN_TAU_SAMPLES) * self.h;
        let normalised = self.adaptation == Adaptation::Normalised;
        [
            (Field::NP, self.n_p >= 1),
            (Field::LS, pos(self.l_s)),
            (Field::H, pos(self.h)),
            (Field::TauKe, pos(self.tau_ke) && !(normalised && self.tau_ke < min_tau)),
            (Field::TauRs, pos(self.tau_rs) && !(normalised && self.tau_rs < min_tau)),
            (Field::F, nonneg(self.f)),
            (Field::GammaKe, nonneg(self.gamma_ke)),
            (Field::IdThreshold, nonneg(self.i_d_threshold)),
            (Field::RS0, nonneg(self.r_s0)),
            (Field::GammaRs, self.gamma_rs.is_finite() && self.gamma_rs <= T::zero()),
            (Field::KE0, self.k_e0.is_finite()),
        ]
        .into_iter()
        .find(|(_, ok)| !ok)
        .map(|(field, _)| field)
    }

    /// Whether `R_s` adapts at a d-current `i_d` \[A\]: `|i_d| > i_d_threshold` and
    /// `γ_Rs ≠ 0` (or the normalised law); thesis 5.1.1. False for a non-finite `i_d`.
    #[inline]
    pub fn r_s_adapts(&self, i_d: T) -> bool {
        i_d.abs() > self.i_d_threshold
            && (self.gamma_rs != T::zero() || self.adaptation == Adaptation::Normalised)
    }
}

/// Shortest time constant of [`Adaptation::Normalised`], in sample times: measured on a
/// 10 kHz log with 1 V of voltage noise, 20 samples diverged and 30 did not.
pub const MIN_TAU_SAMPLES: f64 = 100.0;

/// A setting out of range (the C ABI's error code is `−(1 + its number)`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// [`Settings::n_p`].
    NP = 0,
    /// [`Settings::l_s`].
    LS,
    /// [`Settings::h`].
    H,
    /// [`Settings::tau_ke`].
    TauKe,
    /// [`Settings::tau_rs`].
    TauRs,
    /// [`Settings::f`].
    F,
    /// [`Settings::gamma_ke`].
    GammaKe,
    /// [`Settings::i_d_threshold`].
    IdThreshold,
    /// [`Settings::r_s0`].
    RS0,
    /// [`Settings::gamma_rs`].
    GammaRs,
    /// [`Settings::k_e0`].
    KE0,
    /// `Noise::sigma_i`.
    SigmaI,
    /// `Noise::p0_r_s`.
    P0RS,
    /// `Noise::p0_k_e`.
    P0KE,
    /// `Noise::q_i`.
    QI,
    /// `Noise::q_r_s`.
    QRS,
    /// `Noise::q_k_e`.
    QKE,
    /// The q-axis inductance `L_q` of a salient machine ([`crate::Ipm::new`]).
    LQ,
}

impl Field {
    /// The field's name in the settings (`"l_s"`, `"sigma_i"`, …).
    pub fn name(self) -> &'static str {
        match self {
            Self::NP => "n_p",
            Self::LS => "l_s",
            Self::H => "h",
            Self::TauKe => "tau_ke",
            Self::TauRs => "tau_rs",
            Self::F => "f",
            Self::GammaKe => "gamma_ke",
            Self::IdThreshold => "i_d_threshold",
            Self::RS0 => "r_s0",
            Self::GammaRs => "gamma_rs",
            Self::KE0 => "k_e0",
            Self::SigmaI => "sigma_i",
            Self::P0RS => "p0_r_s",
            Self::P0KE => "p0_k_e",
            Self::QI => "q_i",
            Self::QRS => "q_r_s",
            Self::QKE => "q_k_e",
            Self::LQ => "l_q",
        }
    }
}

/// One sample of a drive: the currents measured at `t_k` and the voltage applied over the
/// coming period `[t_k, t_k + h)` (MODEL.md §4).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample<T> {
    /// d-axis current at `t_k` \[A, peak dq\].
    pub i_d: T,
    /// q-axis current at `t_k` \[A\].
    pub i_q: T,
    /// d-axis voltage over `[t_k, t_k + h)`, its period mean \[V\].
    pub u_d: T,
    /// q-axis voltage, its period mean \[V\].
    pub u_q: T,
    /// Mechanical speed over the period \[rad/s\] (`(ω_m[k] + ω_m[k+1])/2` when known).
    pub w_m: T,
}

impl<T: Real> Sample<T> {
    /// The first channel that is NaN or infinite (0 `i_d`, 1 `i_q`, 2 `u_d`, 3 `u_q`, 4 `w_m`).
    pub fn non_finite(&self) -> Option<usize> {
        [self.i_d, self.i_q, self.u_d, self.u_q, self.w_m].iter().position(|v| !v.is_finite())
    }
}

/// What an observer knows after a sample.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimates<T> {
    /// `K̂_e` \[V s/rad\] (line-to-line RMS per mechanical rad/s).
    pub k_e: T,
    /// `K̂_t = √(3/2) K̂_e` \[N m/A, peak dq current\] (MODEL.md §2).
    pub k_t: T,
    /// `ψ̂_f = √(2/3) K̂_e / n_p` \[V s\].
    pub psi_f: T,
    /// `R̂_s` \[Ω\].
    pub r_s: T,
    /// d-axis error (MRAS) or innovation (Kalman), measured minus predicted current \[A\].
    pub e_d: T,
    /// q-axis error or innovation \[A\].
    pub e_q: T,
    /// Standard error of `K̂_e` \[V s/rad\] (the Kalman filter; 0 for the MRAS).
    pub k_e_se: T,
    /// Standard error of `R̂_s` \[Ω\] (the Kalman filter; 0 for the MRAS).
    pub r_s_se: T,
    /// The normalised innovation squared `νᵀ S⁻¹ ν` of this sample (the Kalman filter; 0 for
    /// the MRAS and at the first sample): χ² with 2 degrees of freedom, mean 2, when the
    /// filter's model and noise levels are right (Bar-Shalom, Li & Kirubarajan, *Estimation
    /// with Applications to Tracking and Navigation*, 2001, §5.4).
    pub nis: T,
    /// Whether `R̂_s` adapted at this sample (always for the Kalman filter).
    pub r_s_active: bool,
}

impl<T: Real> Estimates<T> {
    /// The estimates at `k_e`, `r_s` with the error `(e_d, e_q)`, no standard errors.
    pub fn at(k_e: T, r_s: T, n_p: u32, e_d: T, e_q: T, r_s_active: bool) -> Self {
        Self {
            k_e,
            k_t: T::c(1.5).sqrt() * k_e,
            psi_f: T::c(SQRT_2_3) * k_e / T::c(f64::from(n_p)),
            r_s,
            e_d,
            e_q,
            k_e_se: T::zero(),
            r_s_se: T::zero(),
            nis: T::zero(),
            r_s_active,
        }
    }
}

/// Why an update failed; the observer is then unchanged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fault<T, E> {
    /// A sample's channel (0 `i_d`, 1 `i_q`, 2 `u_d`, 3 `u_q`, 4 `w_m`) is NaN or infinite.
    NonFinite {
        /// The channel.
        channel: usize,
        /// The sample's index.
        sample: u64,
    },
    /// The MRAS's implicit adaptation matrix is singular (not expected).
    Singular {
        /// The sample's index.
        sample: u64,
        /// Its determinant.
        det: T,
    },
    /// The estimates or the state would stop being finite (not expected).
    NotFinite {
        /// The sample's index.
        sample: u64,
        /// `K̂_e` then.
        k_e: T,
        /// `R̂_s` then.
        r_s: T,
    },
    /// The model's step failed.
    Step {
        /// The sample's index.
        sample: u64,
        /// The step's error.
        error: E,
    },
    /// An MRAS output committed to an observer at another sample.
    Stale {
        /// The output's sample.
        output: u64,
        /// The observer's.
        observer: u64,
    },
}
