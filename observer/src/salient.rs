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
//! steps too.

use crate::plant::{Plant, Step, Transition};
use crate::real::{Real, SQRT_2_3, stator_hold_start};
use crate::series::{Aug, Coefficients, advance_substeps};
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
/// [`Settings::hold`]. Operations per step (f64, dq hold at moderate speed): about 22
/// Taylor terms of some 60 multiplications and additions each, no elementary function
/// (the stator hold adds one complex `expm1` for its start voltage).
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
            Hold::Stator => stator_hold_start(u, n_p * s.w_m * self.h),
        };
        let c = Coefficients::at(self.h, r_s, self.l_d, self.l_q, k_e);
        Ok((c, n_p * s.w_m, sqrt_2_3 * s.w_m, u0))
    }
}

impl<T: Real> Ipm<T> {
    /// [`Plant::step`] at the period's coefficients `c`, speeds `w_e`, `emf` and start
    /// voltage `u0` ([`Ipm::period`]).
    ///
    /// # Errors
    /// [`StepError::TooLong`], [`StepError::NotFinite`].
    #[inline]
    fn step_at(
        &self,
        (c, w_e, emf, u0): &(Coefficients<T>, T, T, Complex<T>),
        x: Complex<T>,
        w_m: T,
        relay: bool,
    ) -> Result<Step<T>, StepError> {
        let mut z = Aug { x: [x.re, x.im], v: [u0.re, u0.im], ..Aug::default() };
        if !advance_substeps::<T, true>(c, self.hold, *w_e, *emf, &mut z, T::one()) {
            return Err(StepError::TooLong);
        }
        if !z.x.iter().chain(&z.s[0]).chain(&z.s[3]).all(|v| v.is_finite()) {
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
        Ok(Step { next: pair(z.x), phi_k, phi_r: pair(z.s[0]), psi_k })
    }
}

impl<T: Real> Plant<T> for Ipm<T> {
    type Error = StepError;

    /// The exact step from `x` at `(k_e, r_s)` and its exact sensitivities; `psi_k` for the
    /// relay law is `φ_K/|ω_m|` (0 at standstill, where `K_e` does not act).
    fn step(&self, x: Complex<T>, k_e: T, r_s: T, s: &Sample<T>, relay: bool) -> Result<Step<T>, StepError> {
        self.step_at(&self.period(k_e, r_s, s)?, x, s.w_m, relay)
    }

    /// The step and its transition `Φ = e^{Ah}` column by column: the series' homogeneous
    /// part (no voltage, no back-EMF, no sensitivities) from each unit current, two cheap
    /// propagations where the trait's default takes two more steps with sensitivities.
    fn step_transition(
        &self,
        x: Complex<T>,
        k_e: T,
        r_s: T,
        s: &Sample<T>,
    ) -> Result<Transition<T>, StepError> {
        let period = self.period(k_e, r_s, s)?;
        let st = self.step_at(&period, x, s.w_m, false)?;
        let (c, w_e, emf, _) = period;
        let (zero, one) = (T::zero(), T::one());
        let mut cols = [Aug { x: [one, zero], ..Aug::default() }, Aug { x: [zero, one], ..Aug::default() }];
        for z in &mut cols {
            if !advance_substeps::<T, false>(&c, self.hold, w_e, emf, z, zero) {
                return Err(StepError::TooLong);
            }
        }
        let [d, q] = cols.map(|z| z.x);
        if !d.iter().chain(&q).all(|v| v.is_finite()) {
            return Err(StepError::NotFinite);
        }
        Ok((st, [[d[0], q[0]], [d[1], q[1]]]))
    }
}
