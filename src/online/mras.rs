//! The sampled MRAS observer of `K_e` and `R_s` (thesis 5.1, MODEL.md §7), one sample at
//! a time, without allocation.
//!
//! # Continuous design (thesis eqs. 5.1–5.4)
//!
//! With `i = i_d + j i_q`, `e = i − î`, `emf = √(2/3) ω_m`:
//!
//! ```text
//! L_s dî/dt = u − (R̂_s + j ω_e L_s) î − j emf K̂_e + f L_s e     (observer, F = diag(f, f))
//! dK̂_e/dt = γ_Ke Dᵀ e = −γ_Ke (emf/L_s) e_q                      (Lyapunov; relay: sign(ω_m))
//! dR̂_s/dt = γ_Rs Re(ē i)/|i|   while |i_d| > threshold           (γ_Rs < 0)
//! ```
//!
//! The `R_s` law is the thesis' `γ_Rs e_d` (eq. 5.4) projected on the current direction:
//! it equals `γ_Rs e_d` for a current along +d (the thesis' Exp 1, `i_d = 0.2 i_q > 0`), and
//! it is the Lyapunov direction `−Re(ē i)` for any current. The thesis' literal law has the
//! wrong sign for `i_d < 0`: on `servo_spm_moves_idinj` (−4 A injection) it drove `R̂_s`
//! to −6·10⁵ Ω within 0.4 s. With `sign(i_d)` added it converged there, but ended 0.2 % low
//! in `R_s` (this law: 2·10⁻⁷), because at speed `e_d` also carries the resistance error
//! of the q current rotated by the frame: quasi-statically
//! `e ≈ −(R̃_s i + j emf K̃_e)/(L_s (σ + j ω_e))`, `σ = R_s/L_s + f`, so
//! `e_d ∝ −R̃_s (i_d σ + i_q ω_e)`, whose sign follows `i_q ω_e` rather than `i_d` once
//! `|i_q ω_e| > |i_d| σ`.
//!
//! # Discretisation (exact in the state, implicit in the parameters)
//!
//! **Observer.** Holding the measured error over the period, the observer is the SPM
//! itself plus a correction; we take the exact zero-order-hold step of MODEL.md §4 for the
//! SPM at `(R̂_s, K̂_e)` from the corrected state:
//!
//! ```text
//! î[k+1] = a (î[k] + κ e[k]) + b (u[k] − j emf K̂_e)      (dq hold; stator hold as in pmsm::spm)
//! a = e^{−z h/L_s},  z = R̂_s + j ω_e L_s,  b = (1 − a)/z,  κ = 1 − e^{−f h}
//! ```
//!
//! At the true parameters the error then obeys `e[k+1] = e^{−(R_s/L_s + f + jω_e) h} e[k]`:
//! the continuous observer's error dynamics sampled exactly, stable for every `h` and `f`,
//! and `e = 0` reproduces the plant's exact step (so the observer adds no bias of its
//! own). The alternative of treating the feedback as a resistance `R̂_s + f L_s` driven by
//! `u + f L_s i[k]` is also exact-stable, but its held `i[k]` differs from the plant's
//! moving current within the period, which leaves an error of order `f h Δi` at the true
//! parameters, and that error would bias the adapted `K̂_e`.
//!
//! **Adaptation.** With `φ_K = ∂î[k]/∂K̂_e`, `φ_R = ∂î[k]/∂R̂_s` over the last step
//! (`φ_K = −j b emf`, `φ_R` by differentiating the step), the explicit (Euler) law is
//! `Δθ = Γ Re(Ψᴴ e[k])` with `ψ_K = φ_K ≈ h D` (Lyapunov; relay: `φ_K/|ω_m|`),
//! `ψ_R = φ_R`, `Γ = diag(γ_Ke, −γ_Rs L_s/|i|)`, which is the continuous law times h to
//! first order in h. Its error dynamics: a change `Δθ` changes the a-posteriori error by
//! `−Φ Δθ`, so `K̃⁺ = (1 − g) K̃ + …`, `g = γ_Ke Re(ψ̄_K φ_K) ≈ γ_Ke emf² h²/L_s²`: the
//! explicit step diverges once `g > 2` (e.g. the thesis' `γ_Ke = 0.001` at `h = 1 ms`,
//! 280 rad/s and `L_s = 4.5 mH`: g ≈ 2.6). We solve the law on the a-posteriori error
//! instead (backward Euler in the parameters: the last step re-taken with the new
//! parameters), `Δθ = Γ Re(Ψᴴ (e − Φ Δθ))`, i.e. the 2 × 2 system
//!
//! ```text
//! (I + Γ Re(ΨᴴΦ)) Δθ = Γ Re(Ψᴴ e)
//! ```
//!
//! `Ψ = Φ diag(c)` with `c ≥ 0` (`c_K = 1`, relay `1/|ω_m|`; `c_R = 1`), so
//! `Γ Re(ΨᴴΦ)` is a non-negative diagonal times a positive semi-definite matrix: its
//! eigenvalues are real and ≥ 0, the system is always solvable (determinant ≥ 1; also for
//! the relay at `ω_m = 0`, where `φ_K = 0`) and the self-coupling becomes
//! `1/(1 + g) ∈ (0, 1]`: contractive for every `γ h`. This is the normalised gradient
//! ("projection") algorithm of discrete-time parameter estimation, `Δθ = Γ φ ε/(1 + φᵀΓφ)`
//! (Goodwin & Sin, *Adaptive Filtering, Prediction and Control*, 1984, ch. 3; Ioannou &
//! Sun, *Robust Adaptive Control*, 1996, ch. 4 on normalised adaptive laws and parameter
//! projection). `R̂_s` is projected onto `R̂_s ≥ 0`.
//!
//! # Salient machines (`L_d ≠ L_q`, [`MrasConfig::l_q`])
//!
//! The same design on MODEL.md §2's salient equations, with `L = diag(L_d, L_q)`:
//!
//! ```text
//! L dî/dt = u − R̂_s î − ω_e J L î − j emf K̂_e + f L e       (F = f I, J: rotation by +90°)
//! ```
//!
//! i.e. `L_d dî_d/dt = u_d − R̂_s î_d + ω_e L_q î_q + f L_d e_d`,
//! `L_q dî_q/dt = u_q − R̂_s î_q − ω_e L_d î_d − emf K̂_e + f L_q e_q`. Held error, so the
//! step is again the plant's exact step from the corrected state `î + κ e`, now the
//! augmented exponential of [`crate::pmsm::PmsmIpm`], stepped by the observer crate's
//! [`greybox_observer::Ipm`] (the series of [`ExactPlant::step_derivatives`], to the bit:
//! test `the_core_salient_step_is_the_exact_plants_to_the_bit`; `R̂_s`, `L_d`, `L_q`,
//! `K̂_e`; either hold), so firmware and its C ABI step a salient machine alike, and the
//! error at the true parameters obeys `e[k+1] = (1 − κ) Φ e[k]` with Φ the plant's
//! transition over the period: stable, and zero error reproduces the exact IPM simulation
//! (bit for bit in the tests). The adaptation is the implicit law above with `φ_K`, `φ_R`
//! the sensitivities of this step at the corrected state. The K_e law is then weighted by
//! the back-EMF direction through `L_q` (`φ_K ≈ −j h emf/L_q`: `e_q` times `emf/L_q`, the
//! `Dᵀ e` of the continuous law with `L_q`), the R_s law by the current direction through
//! `L⁻¹` (`φ_R ≈ −h L⁻¹ î`; Γ keeps `l_s = L_d`, so it is exactly the SPM's law for a
//! d-axis injection). Relay: `ψ_K = φ_K/|ω_m|` (0 at `ω_m = 0`, where K_e does not enter
//! the step).
//!
//! **Sensitivities.** Not by finite differences: the step ([`greybox_observer::Ipm`], as
//! [`ExactPlant::step_derivatives`]) carries
//! the forward-sensitivity equations (`Ṡ = A S + ∂f/∂θ`, `S(0) = 0`) inside the same
//! augmented exponential (Van Loan 1978), so `φ_K` and `φ_R` are the exact derivatives of
//! the computed step, to its series tolerance (10⁻¹⁷ relative per block), in the same
//! single evaluation that gives `î[k+1]`. Checked in `tests/it/online.rs`: `φ_K` equals
//! the step from zero current and voltage at unit `K_e` (the step is affine in
//! `(i, u, K_e)`) to rounding (0 difference measured), and `φ_R` a central difference of
//! two steps (`δ = 10⁻⁵ Ω`) to 10⁻⁸ relative, that difference's own truncation and
//! rounding level. It is also cheaper than the difference route: one augmented step with
//! sensitivities took 125 ns against 393 ns for the four plain steps (main, unit `K_e`,
//! `R_s ± δ`) on the development machine; a whole salient update 0.23–0.27 µs (MRAS) and
//! 0.47 µs (the filter, whose transition `Φ` takes the series' homogeneous part from each
//! unit current) in `cargo bench --bench online -- salient`.
//! `l_q = Some(l_s)` is the surface-magnet observer unchanged.

use super::config::MrasConfig;
use crate::error::{Error, Result};
use greybox_observer::Fault;

mod sample;
mod state;
mod step;

pub use sample::Sample;
pub(crate) use state::estimates;
pub use state::{Estimates, INFORMATIVE, MIN_TAU_SAMPLES, Mras, MrasOutput};
pub(crate) use step::{Machine, invalid, machine, settings, step_error};

impl Mras {
    /// An observer with the given settings, started at `k_e0`, `r_s0` and, at the first
    /// sample, at the measured current.
    ///
    /// # Errors
    /// Those of [`MrasConfig::validate`] ([`Error::InvalidOption`] naming the field); with
    /// [`Adaptation::Normalised`](super::Adaptation::Normalised), `tau_ke` or `tau_rs` shorter
    /// than [`MIN_TAU_SAMPLES`] sample times.
    pub fn try_new(config: MrasConfig) -> Result<Self> {
        config.validate()?;
        for (name, tau) in [("tau_ke", config.tau_ke), ("tau_rs", config.tau_rs)] {
            if config.adaptation == super::Adaptation::Normalised && tau < MIN_TAU_SAMPLES * config.h {
                return Err(Error::InvalidOption {
                    option: name.into(),
                    reason: format!(
                        "{tau} s is shorter than {MIN_TAU_SAMPLES} sample times ({} s): an adaptation as fast as the \
                         observer's own error dynamics is unstable",
                        MIN_TAU_SAMPLES * config.h
                    ),
                });
            }
        }
        let settings = step::settings(&config);
        let core = greybox_observer::Mras::new(settings, machine(&config, &settings)?).map_err(invalid)?;
        Ok(Self { core, cfg: config })
    }

    /// The settings.
    pub fn config(&self) -> &MrasConfig {
        &self.cfg
    }

    /// The estimates after the last [`Mras::update`] (the initial ones before any).
    pub fn output(&self) -> Estimates {
        estimates(&self.core.output())
    }

    /// The observer's prediction `(î_d, î_q)` \[A\] of the current at the next sample.
    pub fn predicted_current(&self) -> (f64, f64) {
        self.core.predicted_current()
    }

    /// The model's prediction `(i_d, i_q)` \[A\] of the current at the next sample from the
    /// measured current, voltage and speed of `s` at the estimates `est` (`K̂_e`, `R̂_s`;
    /// no observer correction): what [`crate::online::track`]'s self-check compares with
    /// the next measured current.
    ///
    /// # Errors
    /// Those of the salient model's step ([`Error::Numerical`]).
    pub(crate) fn one_step(&self, s: &Sample, est: &Estimates) -> Result<(f64, f64)> {
        use greybox_observer::Plant;
        let x = crate::pmsm::C64::new(s.i_d, s.i_q);
        let next = self
            .core
            .plant()
            .step(x, est.k_e, est.r_s, &step::sample(s), false)
            .map_err(|e| step_error("MRAS one-step prediction".into(), e))?
            .next;
        Ok((next.re, next.im))
    }

    /// Takes sample k and moves the observer to `t_{k+1}`: [`Mras::compute_output`] then
    /// [`Mras::advance`]. Returns the estimates after the adaptation at `t_k`.
    ///
    /// # Errors
    /// Those of [`Mras::compute_output`]; the observer is then unchanged and may take the
    /// next sample.
    pub fn update(&mut self, s: &Sample) -> Result<Estimates> {
        let out = self.compute_output(s)?;
        self.advance(&out)?;
        Ok(out.estimates)
    }

    /// Compute-output half of [`Mras::update`] (motulator's `compute_output`): the error
    /// `e = i[k] − î[k]`, the implicit adaptation of K̂_e (and of R̂_s while `|i_d|`
    /// exceeds the threshold), and the exact step of the observer to `t_{k+1}` with `u[k]`
    /// and `ω_m`, without changing the observer. The first sample starts the observer at
    /// `i[0]` and adapts nothing.
    ///
    /// # Errors
    /// [`Error::NonFinite`] naming the field (`i_d`, `i_q`, `u_d`, `u_q`, `w_m`) and the
    /// sample's index when a value is NaN or infinite. [`Error::Numerical`] if the
    /// estimates would stop being finite (not expected).
    pub fn compute_output(&self, s: &Sample) -> Result<MrasOutput> {
        let inner = self.core.compute_output(&step::sample(s)).map_err(|f| mras_error(f, s))?;
        Ok(MrasOutput { estimates: estimates(&inner.estimates), inner })
    }

    /// Update half of [`Mras::update`] (motulator's `update`): commits an output of
    /// [`Mras::compute_output`] computed at the observer's present state.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `output`) when `out` was computed for another
    /// sample than the observer's next one; the observer is then unchanged.
    pub fn advance(&mut self, out: &MrasOutput) -> Result<()> {
        self.core.advance(&out.inner).map_err(|f| mras_error(f, &Sample::default()))
    }
}

/// The crate's error for an MRAS fault at sample `s`.
fn mras_error(f: Fault<f64, greybox_observer::StepError>, s: &Sample) -> Error {
    match f {
        Fault::NonFinite { channel, sample } => {
            let (column, value) =
                [("i_d", s.i_d), ("i_q", s.i_q), ("u_d", s.u_d), ("u_q", s.u_q), ("w_m", s.w_m)]
                    [channel.min(4)];
            Error::NonFinite { column: column.into(), row: sample as usize, value }
        }
        Fault::Singular { sample, det } => Error::Numerical {
            context: format!("MRAS adaptation at sample {sample}"),
            reason: format!("implicit adaptation matrix has determinant {det}"),
        },
        Fault::NotFinite { sample, k_e, r_s } => Error::Numerical {
            context: format!("MRAS update at sample {sample}"),
            reason: format!("estimates not finite (k_e = {k_e}, r_s = {r_s})"),
        },
        Fault::Step { sample, error } => step_error(format!("MRAS update at sample {sample}"), error),
        Fault::Stale { output, observer } => Error::InvalidOption {
            option: "output".into(),
            reason: format!("computed for sample {output}, but the observer is at sample {observer}"),
        },
    }
}
