//! The flags of the switching-resolved PWM inverter (`--inverter pwm`) and their conversion
//! into the application layer's [`PwmRequest`].

use crate::app::{Gain, LegWidth, PwmRequest};
use crate::pmsm::{CarrierEdge, Modulator, PwmUpdate};
use clap::Args;
use std::path::PathBuf;

use crate::app::InverterChoice;

/// The PWM inverter's flags, shared by `fit` and `simulate`.
#[derive(Args, Debug, Clone, Default)]
pub struct PwmArgs {
    /// The inverter between the voltage reference and the motor: none (the reference is the
    /// motor's voltage, or the averaged --dead-time model), or pwm: switching-resolved
    /// (modulator, carrier, dead time t_d and device threshold u_th estimated with the
    /// motor, the phase currents' direction inside each period from the model); needs
    /// --voltage reference, theta_m and the DC link (--u-dc or a column u_dc).
    #[arg(help_heading = "Inverter and cable", long, value_enum, default_value_t = InverterChoice::None)]
    pub inverter: InverterChoice,
    /// Zero sequence of the modulator (with --inverter pwm): min-max (= space-vector PWM) or sine.
    #[arg(help_heading = "Inverter and cable", long, value_enum, default_value_t = Modulator::MinMax)]
    pub modulator: Modulator,
    /// Duty-ratio updates per carrier period (with --inverter pwm): double (sampled at the
    /// carrier's peaks and valleys, h = half the carrier period) or single (h = one period).
    #[arg(help_heading = "Inverter and cable", long, value_enum, default_value_t = PwmUpdate::Double)]
    pub pwm_update: PwmUpdate,
    /// Carrier frequency [Hz] (with --inverter pwm), checked against the sample time;
    /// default: 1/(2h) with double update, 1/h with single.
    #[arg(help_heading = "Inverter and cable", long)]
    pub carrier_hz: Option<f64>,
    /// Levels of the PWM counter per half carrier period (with --inverter pwm): duty ratios
    /// are rounded to them; default: continuous.
    #[arg(help_heading = "Inverter and cable", long)]
    pub pwm_levels: Option<u32>,
    /// The carrier's direction over the log's first period (with --inverter pwm); default:
    /// chosen by the lower one-step loss at the start.
    #[arg(help_heading = "Inverter and cable", long, value_enum)]
    pub carrier_first: Option<CarrierEdge>,
    /// Width i_w [A] of the smooth leg state (2/π)·atan(i/i_w) that parasitic capacitances
    /// (and the current's noise) give near zero current, `estimate` (a nuisance parameter,
    /// the default), or `sign` (a hard switch-over).
    #[arg(help_heading = "Inverter and cable", long, value_parser = |s: &str| s.parse::<LegWidth>())]
    pub leg_state_width: Option<LegWidth>,
    /// Gain k_o of the PWM model's one-step predictor (with --inverter pwm): 1 restarts every
    /// period from the measured current (the default), lower values trust the model more
    /// (for noisy currents), `estimate` fits it as a nuisance parameter.
    #[arg(help_heading = "Inverter and cable", long, value_parser = |s: &str| s.parse::<Gain>())]
    pub predictor_gain: Option<Gain>,
    /// The inverter's known parameters from a JSON file: keys t_d [s], u_th [V], r_on [Ω],
    /// i_w [A] (a datasheet), or a fit report of --inverter pwm (its `parameters`); the
    /// ones given are held fixed.
    #[arg(help_heading = "Inverter and cable", long)]
    pub inverter_params: Option<PathBuf>,
}

impl From<&PwmArgs> for PwmRequest {
    fn from(a: &PwmArgs) -> Self {
        Self {
            inverter: a.inverter,
            modulator: a.modulator,
            pwm_update: a.pwm_update,
            carrier_hz: a.carrier_hz,
            pwm_levels: a.pwm_levels,
            carrier_first: a.carrier_first,
            leg_state_width: a.leg_state_width,
            predictor_gain: a.predictor_gain,
            inverter_params: a.inverter_params.clone(),
        }
    }
}
