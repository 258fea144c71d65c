//! A simulated machine stepped with the offline models' own exact steps (MODEL.md §2, §4):
//! the drive simulator advances its plant with [`PmsmSpm`]'s closed-form step or
//! [`PmsmIpm`]'s augmented exponential, one period at a time, so a log from the simulator
//! is reproduced exactly by the model that fits it.

use crate::error::{Error, Result};
use crate::model::GreyBoxModel;
use crate::pmsm::log::signals::check_pole_pairs;
use crate::pmsm::model::augmented::{Aug, IpmCoefficients, IpmInputs, advance_at};
use crate::pmsm::model::interval::{
    C64, IntervalSource, SQRT_2_3, VoltageHold, check_finite, check_positive,
};
use crate::pmsm::model::ipm::PmsmIpm;
use crate::pmsm::model::spm::PmsmSpm;
use crate::pmsm::model::spm::SpmInputs;
use greybox_observer::SENS_R_K;
use serde::{Deserialize, Serialize};

/// One exact step with its derivatives: see [`ExactPlant::step_derivatives`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepDerivatives {
    /// The dq current `[i_d, i_q]` \[A\] at the end of the period.
    pub next: [f64; 2],
    /// `∂next/∂R_s` at the fixed start current \[A/Ω\].
    pub d_r_s: [f64; 2],
    /// `∂next/∂K_e` at the fixed start current \[A/(V s/rad)\].
    pub d_k_e: [f64; 2],
}

/// The electrical parameters of a machine (MODEL.md §2).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotorParameters {
    /// Stator resistance `R_s` \[Ω\].
    pub r_s: f64,
    /// d-axis inductance `L_d` \[H\].
    pub l_d: f64,
    /// q-axis inductance `L_q` \[H\] (`= l_d` for surface magnets).
    pub l_q: f64,
    /// Magnet flux linkage `ψ_f` \[V s\] (amplitude-invariant).
    pub psi_f: f64,
    /// Pole pairs `n_p`.
    pub n_p: u32,
}

impl MotorParameters {
    /// Back-EMF constant `K_e = √(3/2) n_p ψ_f` \[V s/rad\] (MODEL.md §2).
    pub fn k_e(&self) -> f64 {
        f64::from(self.n_p) * self.psi_f / SQRT_2_3
    }

    /// Torque constant `K_t = 1.5 n_p ψ_f` \[N m per A of peak dq current\].
    pub fn k_t(&self) -> f64 {
        1.5 * f64::from(self.n_p) * self.psi_f
    }

    /// Electromagnetic torque `T_e = 1.5 n_p (ψ_f i_q + (L_d − L_q) i_d i_q)` \[N m\] at the dq
    /// currents `i_d, i_q` \[A, peak\] (MODEL.md §2).
    pub fn torque(&self, i_d: f64, i_q: f64) -> f64 {
        1.5 * f64::from(self.n_p) * (self.psi_f * i_q + (self.l_d - self.l_q) * i_d * i_q)
    }

    /// Whether `L_d ≠ L_q` (interior magnets).
    pub fn salient(&self) -> bool {
        self.l_d != self.l_q
    }

    /// Checks the values.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `r_s`, `l_d`, `l_q` (not positive and finite) or
    /// `psi_f` (not finite); [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError::InvalidPolePairs) for `n_p = 0`.
    pub fn validate(&self) -> Result<()> {
        check_positive("r_s", self.r_s)?;
        check_positive("l_d", self.l_d)?;
        check_positive("l_q", self.l_q)?;
        check_finite("psi_f", self.psi_f)?;
        check_pole_pairs(self.n_p)
    }
}

/// One-period inputs of the model that steps the plant.
#[derive(Clone, Debug)]
enum Engine {
    Spm(PmsmSpm, SpmInputs),
    Ipm(PmsmIpm, IpmInputs),
}

/// The exact electrical step of a machine at the period's mean speed, the voltage held in
/// the stator frame over each period (an inverter's output) or in dq (some simulators).
#[derive(Clone, Debug)]
pub struct ExactPlant {
    engine: Engine,
    h: f64,
    n_p: u32,
    hold: VoltageHold,
}

impl ExactPlant {
    /// The plant of a machine with `n_p` pole pairs at sample time `h` \[s\] with the given
    /// voltage hold; salient machines step with the augmented exponential, the others in
    /// closed form.
    ///
    /// # Errors
    /// [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError::InvalidPolePairs) for `n_p = 0`; [`Error::InvalidSampleTime`] for `h` not
    /// positive and finite.
    pub fn new(n_p: u32, h: f64, salient: bool, hold: VoltageHold) -> Result<Self> {
        check_pole_pairs(n_p)?;
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidSampleTime { h });
        }
        let source = IntervalSource::one(h, f64::from(n_p));
        let engine = if salient {
            Engine::Ipm(PmsmIpm::new(n_p, hold), IpmInputs { source, hold, dt: Vec::new() })
        } else {
            Engine::Spm(PmsmSpm::new(n_p, hold), SpmInputs { source, dt: Vec::new() })
        };
        Ok(Self { engine, h, n_p, hold })
    }

    /// The dq current `[i_d, i_q]` \[A\] at the end of the period from `i` at its start, for
    /// the dq voltage `u0` \[V\] at the start of the period (held in the stator frame it turns
    /// backwards in dq by `ω_e h` over the period; held in dq it stays) and the period's
    /// mean mechanical speed `w_m` \[rad/s\]: the step of [`PmsmSpm`] or [`PmsmIpm`].
    ///
    /// # Errors
    /// Those of the model's `coefficients` (the parameters are validated every step: they
    /// may change with temperature); [`Error::Numerical`] for a non-finite result.
    pub fn step(&mut self, p: &MotorParameters, i: [f64; 2], u0: C64, w_m: f64) -> Result<[f64; 2]> {
        let mut next = [0.0; 2];
        match &mut self.engine {
            Engine::Spm(model, inp) => {
                inp.source.set_one(w_m, u0);
                let c = model.coefficients(&[p.r_s, p.l_d, p.k_e()], inp)?;
                model.step(&c, inp, 0, &i, &mut next);
            }
            Engine::Ipm(model, inp) => {
                inp.source.set_one(w_m, u0);
                let c = model.coefficients(&[p.r_s, p.l_d, p.l_q, p.k_e()], inp)?;
                model.step(&c, inp, 0, &i, &mut next);
            }
        }
        if next.iter().all(|x| x.is_finite()) {
            Ok(next)
        } else {
            Err(Error::Numerical {
                context: "plant step".into(),
                reason: format!(
                    "non-finite current from i = {i:?} A, u0 = {u0} V, w_m = {w_m} rad/s with {p:?}"
                ),
            })
        }
    }

    /// [`ExactPlant::step`] of a salient plant together with the exact derivatives of the
    /// end current with respect to `R_s` and `K_e` at the fixed start current `i`: the
    /// forward sensitivities of [`PmsmIpm`]'s augmented exponential started at zero (Van
    /// Loan 1978; [`PmsmIpm`]), one augmented step, no finite difference. Takes `&self`
    /// and allocates nothing unless it fails. The observers step with
    /// [`greybox_observer::Ipm`], the same series and the same numbers to the bit (where at
    /// most 64 substeps are needed; beyond, this forms the matrix by scaling and squaring
    /// where `Ipm` fails). Unlike [`ExactPlant::step`] it accepts `R_s = 0` (an estimate at
    /// its bound). `n_p` of `p` is ignored (the plant's own is used).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `salient`) for a plant made with `salient = false`;
    /// [`Error::InvalidParameter`] naming `r_s` (negative or not finite), `l_d`, `l_q` (not
    /// positive and finite) or `psi_f` (not finite); [`Error::Numerical`] for a non-finite
    /// result.
    pub fn step_derivatives(
        &self,
        p: &MotorParameters,
        i: [f64; 2],
        u0: C64,
        w_m: f64,
    ) -> Result<StepDerivatives> {
        if !matches!(self.engine, Engine::Ipm(..)) {
            return Err(Error::InvalidOption {
                option: "salient".into(),
                reason: "step_derivatives needs the plant of a salient machine (ExactPlant::new with salient = true)"
                    .into(),
            });
        }
        if !(p.r_s.is_finite() && p.r_s >= 0.0) {
            return Err(Error::InvalidParameter {
                name: "r_s".into(),
                value: p.r_s,
                reason: "must be finite and at least 0".into(),
            });
        }
        check_positive("l_d", p.l_d)?;
        check_positive("l_q", p.l_q)?;
        check_finite("psi_f", p.psi_f)?;
        let w_e = f64::from(self.n_p) * w_m;
        let k_e = f64::from(self.n_p) * p.psi_f / SQRT_2_3;
        let c = IpmCoefficients::at(self.h, p.r_s, p.l_d, p.l_q, k_e);
        let mut z = Aug { x: i, v: [u0.re, u0.im], ..Aug::default() };
        advance_at::<SENS_R_K>(&c, self.hold, w_e, SQRT_2_3 * w_m, &mut z, 1.0);
        let out = StepDerivatives { next: z.x, d_r_s: z.s[0], d_k_e: z.s[3] };
        if out.next.iter().chain(&out.d_r_s).chain(&out.d_k_e).all(|x| x.is_finite()) {
            Ok(out)
        } else {
            Err(Error::Numerical {
                context: "plant step".into(),
                reason: format!(
                    "non-finite current or derivative from i = {i:?} A, u0 = {u0} V, w_m = {w_m} rad/s with {p:?}"
                ),
            })
        }
    }
}
