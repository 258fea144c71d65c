//! The salient machine's exact step ([`Ipm`]): the exponential of an augmented autonomous
//! linear system applied to a vector (Van Loan 1978, "Computing integrals involving the
//! matrix exponential", IEEE TAC 23(3); MODEL.md §4), with its forward sensitivities to
//! `R_s`, `L_d`, `L_q` and `K_e` in the same series, in `f32` or `f64` without allocation.
//!
//! Over one period at the mean speed (`ω_e = n_p ω_m`) the dq currents follow
//! `L_d i_d' = u_d − R_s i_d + ω_e L_q i_q`, `L_q i_q' = u_q − R_s i_q − ω_e L_d i_d −
//! √(2/3) ω_m K_e`, the voltage held in dq or turning backwards at `ω_e` (held in the stator
//! frame). The augmented state `z = (i, S, v, 1)` (13 components: the current, its four
//! sensitivity columns, the voltage and the constant) obeys `z' = M z`, and the step is
//! `e^{Mh} z`, summed as the Taylor series `Σ (Mh)^j z / j!` on the vector with structured
//! products, in substeps that keep the spectral scale `ρ = τ (R_s/min(L) + |ω_e|) ≤ 0.5`.
//! The series is [`crate::advance_substeps`], with which `greybox`'s offline interior-magnet model
//! steps too; the observers carry the sensitivities to `R_s` and `K_e` only
//! ([`crate::SENS_R_K`]; the offline fit all four), the same numbers for those to the bit.

use crate::plant::{Plant, Step, Transition};
use crate::real::{Real, SQRT_2_3, stator_hold_start_sin};
use crate::series::{Aug, Coefficients, SENS_R_K, advance_substeps, advance_substeps_transition};
use crate::types::{Field, Hold, Sample, Settings};
use num_complex::Complex;

/// Why the salient step failed (the observer is then unchanged).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepError {
    /// The running `R_s` is negative or not finite (it must be at least 0).
    Resistance,
    /// The running `K_e` is not finite.
    BackEmf,
    /// More than [`crate::MAX_SUBSTEPS`] substeps (or a spectral scale that is not finite).
    TooLong,
    /// The step or its sensitivities are not finite.
    NotFinite,
}

impl core::fmt::Display for StepError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Resistance => "the running R_s is negative or not finite",
            Self::BackEmf => "the running K_e is not finite",
            Self::TooLong => {
                "the period is too long for the series (more than 64 substeps of the salient step)"
            }
            Self::NotFinite => "the salient step's current or sensitivities are not finite",
        })
    }
}

/// The salient (interior-magnet) machine's exact one-period step with its sensitivities to
/// `K_e` and `R_s` (module documentation): `L_d` and `L_q` known, the voltage held as
/// [`Settings::hold`]. Operations per step (f64): 10 to 17 Taylor terms (the spectral scale
/// `ρ` from 0.04 to 0.5) of some 50 multiplications and additions each and the stopping
/// test, no elementary function (the stator hold adds two sines for its start voltage); the
/// filter's transition adds the 2 × 2 matrix's series, some 20 operations a term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ipm<T> {
    n_p: u32,
    l_d: T,
    l_q: T,
    h: T,
    hold: Hold,
}

impl<T: Real> Ipm<T> {
    /// The step of the machine of `settings` (`n_p`, `h`, `hold`; `l_s` is `L_d`) with
    /// `L_q = l_q` \[H\].
    ///
    /// # Errors
    /// [`Field::LQ`] for an `l_q` that is not positive and finite; the first field of
    /// `settings` out of range ([`Settings::invalid`]).
    pub fn new(settings: &Settings<T>, l_q: T) -> Result<Self, Field> {
        if let Some(field) = settings.invalid() {
            return Err(field);
        }
        if !(l_q.is_finite() && l_q > T::zero()) {
            return Err(Field::LQ);
        }
        Ok(Self { n_p: settings.n_p, l_d: settings.l_s, l_q, h: settings.h, hold: settings.hold })
    }
}

impl<T: Real> Ipm<T> {
    /// The period's coefficients at `(k_e, r_s)` and its speeds: `(c, ω_e, emf)`, and the
    /// start voltage of `s` \[V\] for the hold.
    ///
    /// # Errors
    /// [`StepError::Resistance`], [`StepError::BackEmf`].
    #[inline]
    fn period(
        &self,
        k_e: T,
        r_s: T,
        s: &Sample<T>,
    ) -> Result<(Coefficients<T>, T, T, Complex<T>), StepError> {
        if !(r_s.is_finite() && r_s >= T::zero()) {
            return Err(StepError::Resistance);
        }
        let n_p = T::c(f64::from(self.n_p));
        let sqrt_2_3 = T::c(SQRT_2_3);
        // K_e through ψ_f and back, as `greybox`'s plant of the offline model takes it:
        // the same number to the bit as `greybox track` has always stepped with.
        let psi_f = sqrt_2_3 * k_e / n_p;
        if !psi_f.is_finite() {
            return Err(StepError::BackEmf);
        }
        let k_e = n_p * psi_f / sqrt_2_3;
        let u = Complex::new(s.u_d, s.u_q);
        let u0 = match self.hold {
            Hold::Dq => u,
            Hold::Stator => {
                // One sine beside the half angle's, where the complex `expm1` takes a sine
                // and cosine pair, a sine, `exp` and `expm1`: the same number to the bit.
                let phi = n_p * s.w_m * self.h;
                stator_hold_start_sin(u, phi, phi.sin())
            }
        };
        let c = Coefficients::at(self.h, r_s, self.l_d, self.l_q, k_e);
        Ok((c, n_p * s.w_m, sqrt_2_3 * s.w_m, u0))
    }
}

impl<T: Real> Ipm<T> {
    /// [`Plant::step`] at the period's coefficients `c`, speeds `w_e`, `emf` and start
    /// voltage `u0` ([`Ipm::period`]), with `PHI` also the period's transition `Φ`
    /// (row-major; [`crate::advance_substeps_transition`]), without it `I + hA`.
    ///
    /// # Errors
    /// [`StepError::TooLong`], [`StepError::NotFinite`].
    #[inline]
    fn step_at<const PHI: bool>(
        &self,
        (c, w_e, emf, u0): &(Coefficients<T>, T, T, Complex<T>),
        x: Complex<T>,
        w_m: T,
        relay: bool,
    ) -> Result<(Step<T>, [T; 4]), StepError> {
        let mut z = Aug { x: [x.re, x.im], v: [u0.re, u0.im], ..Aug::default() };
        let phi = match PHI {
            true => advance_substeps_transition::<T, SENS_R_K>(c, self.hold, *w_e, *emf, &mut z, T::one()),
            false => advance_substeps::<T, SENS_R_K>(c, self.hold, *w_e, *emf, &mut z, T::one())
                .then_some([T::zero(); 4]),
        }
        .ok_or(StepError::TooLong)?;
        if !z.x.iter().chain(&z.s[0]).chain(&z.s[3]).chain(&phi).all(|v| v.is_finite()) {
            return Err(StepError::NotFinite);
        }
        let pair = |v: [T; 2]| Complex::new(v[0], v[1]);
        let phi_k = pair(z.s[3]);
        let psi_k = match relay {
            false => phi_k,
            // φ_K is proportional to ω_m (its direction depends on ω_m only through the
            // rotation within the period).
            true if w_m != T::zero() => phi_k / w_m.abs(),
            true => Complex::default(),
        };
        Ok((Step { next: pair(z.x), phi_k, phi_r: pair(z.s[0]), psi_k }, phi))
    }
}

impl<T: Real> Plant<T> for Ipm<T> {
    type Error = StepError;

    /// The exact step from `x` at `(k_e, r_s)` and its exact sensitivities; `psi_k` for the
    /// relay law is `φ_K/|ω_m|` (0 at standstill, where `K_e` does not act).
    fn step(&self, x: Complex<T>, k_e: T, r_s: T, s: &Sample<T>, relay: bool) -> Result<Step<T>, StepError> {
        Ok(self.step_at::<false>(&self.period(k_e, r_s, s)?, x, s.w_m, relay)?.0)
    }

    /// The step and its transition `Φ = e^{Ah}`: the series' homogeneous part (no voltage,
    /// no back-EMF, no sensitivities) as the Taylor series of the 2 × 2 matrix, summed in
    /// the step's own loop ([`crate::advance_substeps_transition`]), where the trait's
    /// default takes two more steps with sensitivities.
    fn step_transition(
        &self,
        x: Complex<T>,
        k_e: T,
        r_s: T,
        s: &Sample<T>,
    ) -> Result<Transition<T>, StepError> {
        let (st, phi) = self.step_at::<true>(&self.period(k_e, r_s, s)?, x, s.w_m, false)?;
        Ok((st, [[phi[0], phi[1]], [phi[2], phi[3]]]))
    }
}
