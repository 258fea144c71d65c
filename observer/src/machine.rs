//! The machine an observer steps ([`Machine`]): surface magnets in closed form ([`Spm`]) or
//! a salient machine by its augmented exponential ([`Ipm`]), chosen by the settings.

use crate::plant::{Plant, Spm, Step, Transition};
use crate::real::Real;
use crate::salient::{Ipm, StepError};
use crate::types::{Field, Sample, Settings};
use num_complex::Complex;

/// The observers' model of the machine: [`Spm`] where `L_d = L_q`, else [`Ipm`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Machine<T> {
    /// Surface magnets, `L_d = L_q = l_s`: the closed-form step.
    Spm(Spm<T>),
    /// A salient machine, `L_d ≠ L_q`: the augmented exponential.
    Ipm(Ipm<T>),
}

impl<T: Real> Machine<T> {
    /// The machine of `settings` (`l_s` is `L_d`) with `L_q = l_q` \[H\]: salient where
    /// `l_q` is given and differs from `l_s`, else surface magnets.
    ///
    /// # Errors
    /// Those of [`Ipm::new`] for a salient machine (a bad `l_q`, [`Field::LQ`]).
    pub fn of(settings: &Settings<T>, l_q: Option<T>) -> Result<Self, Field> {
        match l_q {
            Some(l_q) if l_q != settings.l_s => Ipm::new(settings, l_q).map(Self::Ipm),
            _ => Ok(Self::Spm(Spm::new(settings))),
        }
    }
}

impl<T: Real> Plant<T> for Machine<T> {
    type Error = StepError;

    #[inline]
    fn step(&self, x: Complex<T>, k_e: T, r_s: T, s: &Sample<T>, relay: bool) -> Result<Step<T>, StepError> {
        match self {
            Self::Spm(spm) => Ok(spm.step_factor(x, k_e, r_s, s, relay).0),
            Self::Ipm(ipm) => ipm.step(x, k_e, r_s, s, relay),
        }
    }

    /// Surface magnets in closed form; a salient machine by the series' homogeneous part
    /// ([`Ipm`]'s `step_transition`).
    #[inline]
    fn step_transition(
        &self,
        x: Complex<T>,
        k_e: T,
        r_s: T,
        s: &Sample<T>,
    ) -> Result<Transition<T>, StepError> {
        match self {
            Self::Spm(spm) => Ok(spm.step_transition(x, k_e, r_s, s).unwrap_or_else(|e| match e {})),
            Self::Ipm(ipm) => ipm.step_transition(x, k_e, r_s, s),
        }
    }
}
