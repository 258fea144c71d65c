//! The observers' model of the machine (see the parent module's documentation): the
//! surface-magnet step of [`greybox_observer::Spm`] in closed form, or the salient step
//! through [`ExactPlant`] (augmented exponential with its sensitivities), as a
//! [`greybox_observer::Plant`]; and the conversions between the crate's types and the
//! observer crate's.

use super::super::config::{Adaptation, MrasConfig};
use super::sample::Sample;
use crate::error::{Error, Result};
use crate::pmsm::{C64, ExactPlant, MotorParameters, SQRT_2_3, VoltageHold, stator_hold_start};
use greybox_observer::{Field, Hold, Plant, Settings, Spm, Step, Transition};

/// The observers' model: surface magnets in closed form, or a salient machine.
#[derive(Clone, Debug)]
pub(crate) enum Machine {
    /// `L_d = L_q`: the closed-form step.
    Spm(Spm<f64>),
    /// `L_d ≠ L_q`: the plant's augmented exponential.
    Salient(Box<Salient>),
}

/// The salient step's plant and machine.
#[derive(Clone, Debug)]
pub(crate) struct Salient {
    plant: ExactPlant,
    n_p: u32,
    l_d: f64,
    l_q: f64,
    h: f64,
    hold: VoltageHold,
}

impl Machine {
    /// The model of `config` (validated; `settings` its observer crate's settings): the
    /// salient step when [`MrasConfig::salient`] (`l_s` is `L_d`), else the surface-magnet
    /// one. Both observers build theirs here.
    ///
    /// # Errors
    /// Those of [`ExactPlant::new`] for a salient machine.
    pub(crate) fn of(config: &MrasConfig, settings: &Settings<f64>) -> Result<Self> {
        if !config.salient() {
            return Ok(Self::Spm(Spm::new(settings)));
        }
        Ok(Self::Salient(Box::new(Salient {
            plant: ExactPlant::new(config.n_p, config.h, true, config.hold)?,
            n_p: config.n_p,
            l_d: config.l_s,
            l_q: config.l_q.unwrap_or(config.l_s),
            h: config.h,
            hold: config.hold,
        })))
    }
}

impl Plant<f64> for Machine {
    type Error = Error;

    fn step(
        &self,
        x: C64,
        k_e: f64,
        r_s: f64,
        s: &greybox_observer::Sample<f64>,
        relay: bool,
    ) -> Result<Step<f64>> {
        match self {
            Self::Spm(spm) => Ok(spm.step_factor(x, k_e, r_s, s, relay).0),
            Self::Salient(m) => m.step(x, k_e, r_s, s, relay),
        }
    }

    fn step_transition(
        &self,
        x: C64,
        k_e: f64,
        r_s: f64,
        s: &greybox_observer::Sample<f64>,
    ) -> Result<Transition<f64>> {
        match self {
            Self::Spm(spm) => Ok(spm.step_transition(x, k_e, r_s, s).unwrap_or_else(|e| match e {})),
            // By the step's linearity in the current (the trait's default): two more steps.
            Self::Salient(m) => m.step_transition(x, k_e, r_s, s),
        }
    }
}

impl Plant<f64> for Salient {
    type Error = Error;

    /// The exact salient step from the corrected state `x` at `(k_e, r_s)` and its exact
    /// sensitivities (module documentation).
    fn step(
        &self,
        x: C64,
        k_e: f64,
        r_s: f64,
        s: &greybox_observer::Sample<f64>,
        relay: bool,
    ) -> Result<Step<f64>> {
        let n_p = self.n_p;
        let p = MotorParameters {
            r_s,
            l_d: self.l_d,
            l_q: self.l_q,
            psi_f: SQRT_2_3 * k_e / f64::from(n_p),
            n_p,
        };
        let u = C64::new(s.u_d, s.u_q);
        let u0 = match self.hold {
            VoltageHold::Dq => u,
            VoltageHold::Stator => stator_hold_start(u, f64::from(n_p) * s.w_m * self.h),
        };
        let d = self.plant.step_derivatives(&p, [x.re, x.im], u0, s.w_m)?;
        let c = |v: [f64; 2]| C64::new(v[0], v[1]);
        let phi_k = c(d.d_k_e);
        let psi_k = match relay {
            false => phi_k,
            // φ_K is proportional to ω_m (its direction depends on ω_m only through the
            // rotation within the period): φ_K/|ω_m|, and 0 at standstill where K_e has
            // no effect on the step.
            true if s.w_m != 0.0 => phi_k / s.w_m.abs(),
            true => C64::default(),
        };
        Ok(Step { next: c(d.next), phi_k, phi_r: c(d.d_r_s), psi_k })
    }
}

/// The observer crate's settings of `config`.
pub(crate) fn settings(config: &MrasConfig) -> Settings<f64> {
    Settings {
        n_p: config.n_p,
        hold: match config.hold {
            VoltageHold::Dq => Hold::Dq,
            VoltageHold::Stator => Hold::Stator,
        },
        adaptation: match config.adaptation {
            Adaptation::Lyapunov => greybox_observer::Adaptation::Lyapunov,
            Adaptation::Relay => greybox_observer::Adaptation::Relay,
            Adaptation::Normalised => greybox_observer::Adaptation::Normalised,
        },
        l_s: config.l_s,
        h: config.h,
        f: config.f,
        gamma_ke: config.gamma_ke,
        gamma_rs: config.gamma_rs,
        tau_ke: config.tau_ke,
        tau_rs: config.tau_rs,
        i_d_threshold: config.i_d_threshold,
        k_e0: config.k_e0,
        r_s0: config.r_s0,
    }
}

/// The observer crate's sample of `s`.
pub(super) fn sample(s: &Sample) -> greybox_observer::Sample<f64> {
    greybox_observer::Sample { i_d: s.i_d, i_q: s.i_q, u_d: s.u_d, u_q: s.u_q, w_m: s.w_m }
}

/// A setting the observer crate refused (the crate's own checks run first: not expected).
pub(crate) fn invalid(field: Field) -> Error {
    Error::InvalidOption { option: field.name().into(), reason: "out of range".into() }
}
