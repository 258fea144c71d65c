//! The inverter inside the model: a switching-resolved PWM voltage source for the SPM and
//! IPM current equations, driven by the controller's voltage reference (MODEL.md §4,
//! "Reference versus actual voltage"; §8).
//!
//! From each period's reference (after its computational delay and modulator angle
//! advance, as [`VoltageInput::Reference`](crate::pmsm::VoltageInput::Reference) says) the modulator forms the legs' duty
//! ratios, the carrier comparison their switching instants ([`modulator`]), and the dead
//! time blanks each leg after its switching instant; during blanking the leg follows the
//! direction of its phase current *as the model predicts it at that instant inside the
//! period*, and every leg loses the conducting device's threshold voltage. Between those
//! instants the phase voltages are constant and each piece is an exact step of the current
//! equations ([`period`]), so the ripple near a current's zero crossing, which a period
//! average cannot represent, is in the model. The inverter's `t_d` \[s\] and `u_th` \[V\]
//! (and on request the leg-state width `i_w` \[A\]) are nuisance parameters estimated with
//! the motor's, or known; a device on-resistance `r_on` acts as a series resistance (it
//! cannot be told from `R_s`: MODEL.md §6) and is given, not estimated.
//!
//! Sensitivities are exact derivatives of the step by forward-mode differentiation
//! ([`dual`]), including those through the switching instants the dead time moves.

mod acceleration;
mod angle_speed;
pub(crate) mod dual;
mod inverter;
mod kernel;
pub(crate) mod modulator;
mod noise;
pub(crate) mod period;

use period::{Params, Period};

pub use inverter::{CarrierEdge, Modulator, PwmInverter, PwmUpdate};

mod model;
pub use model::{PmsmPwm, PwmCoefficients, PwmInputs, SignMargin};

/// The switching-resolved inverter as a drive simulator's plant: the carrier's state
/// between periods and the step of one period.
#[derive(Clone, Debug, Default)]
pub(crate) struct PwmPlantStep {
    carrier: modulator::Carrier,
    k: usize,
}

impl PwmPlantStep {
    /// One period of length `h` \[s\] from the dq current `i` \[A\] at electrical angle
    /// `theta_e` \[rad\], interval-mean mechanical speed `w_m` \[rad/s\] changing at
    /// `[a_e, a_m]` \[rad/s², electrical and mechanical\] over the period (the acceleration's
    /// term, `acceleration`), of the stator voltage
    /// reference `u_ab` \[V\] the modulator applies at DC link `u_dc` \[V\], for the motor
    /// `(r, l_d, l_q, k_e)` \[Ω, H, H, V s/rad\] and inverter `(t_d, u_th, i_w)` \[s, V, A; i_w 0
    /// for the sign\]: the current at the period's end and the period-mean dq voltage \[V\].
    /// The first period's carrier rises.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn step(
        &mut self,
        inv: &PwmInverter,
        motor: [f64; 4],
        inverter: [f64; 3],
        i: [f64; 2],
        theta_e: f64,
        w_e: f64,
        w_m: f64,
        [a_e, a_m]: [f64; 2],
        u_ab: [f64; 2],
        u_dc: f64,
        h: f64,
    ) -> ([f64; 2], [f64; 2]) {
        let d = modulator::duty_ratios(inv, u_ab[0], u_ab[1], u_dc);
        let rising = self.k.is_multiple_of(2);
        self.k += 1;
        let per =
            Period::new(theta_e, w_e, w_m, u_dc, modulator::halves(inv, &mut self.carrier, d, rising, h))
                .accelerating(a_e, a_m);
        let [r, l_d, l_q, k_e] = motor;
        let [t_d, u_th, i_w] = inverter;
        let q = Params { r, l_d, l_q, k_e, t_d, u_th, i_w: (i_w > 0.0).then_some(i_w) };
        period::step_mean(&q, &per, i, h)
    }
}
