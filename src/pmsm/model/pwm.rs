//! The inverter inside the model: a switching-resolved PWM voltage source for the SPM and
//! IPM current equations, driven by the controller's voltage reference (MODEL.md §4,
//! "Reference versus actual voltage"; §8).
//!
//! From each period's reference (after its computational delay and modulator angle
//! advance, as [`VoltageInput::Reference`] says) the modulator forms the legs' duty
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

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Parameter, Sensitivities};
use crate::pmsm::log::signals::{DqView, channel, check_pole_pairs};
use crate::pmsm::model::interval::{
    SQRT_2_3, VoltageInput, controller_frame, mean_speed, reference_channels,
};
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;
use serde::{Deserialize, Serialize};

pub(crate) mod dual;
pub(crate) mod modulator;
pub(crate) mod period;

use dual::{Dual, N, Scalar};
use period::{Params, Period};

/// Start of the estimated predictor gain k_o: the restart from the measured current, the
/// gain of the default fit.
pub const PREDICTOR_GAIN_START: f64 = 1.0;

/// The DC-link voltage column a log may carry \[V\].
pub const U_DC: &str = "u_dc";

/// How the modulator forms the legs' duty ratios from the voltage reference.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Modulator {
    /// Min-max zero sequence (equal to symmetric space-vector PWM), the common default.
    #[default]
    #[cfg_attr(feature = "cli", value(name = "min-max"))]
    MinMax,
    /// Sinusoidal PWM, no zero sequence.
    Sine,
}

/// How often the duty ratios are updated per carrier period.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum PwmUpdate {
    /// Twice, sampled at the carrier's peaks and valleys: the sample period is half the
    /// carrier period.
    #[default]
    Double,
    /// Once: the sample period is the carrier period.
    Single,
}

/// The carrier's direction over the log's first half carrier period.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CarrierEdge {
    /// Rising: every switching leg turns on.
    Rising,
    /// Falling: every switching leg turns off.
    Falling,
}

/// The PWM inverter between the voltage reference and the motor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PwmInverter {
    /// DC-link voltage U_dc \[V\]; `None`: the log's column `u_dc`.
    #[serde(default)]
    pub u_dc: Option<f64>,
    /// Carrier frequency \[Hz\]; `None`: `1/(2h)` (double update) or `1/h` (single), the
    /// only ones a sample period synchronised with the carrier allows; a given value is
    /// checked against them.
    #[serde(default)]
    pub carrier_hz: Option<f64>,
    /// Zero sequence of the modulator.
    #[serde(default)]
    pub modulator: Modulator,
    /// Duty-ratio updates per carrier period.
    #[serde(default)]
    pub update: PwmUpdate,
    /// Levels of the PWM counter per half carrier period (duty ratios rounded to them);
    /// `None`: continuous duty ratios.
    #[serde(default)]
    pub levels: Option<u32>,
    /// The carrier's direction over the first period; `None`: chosen by the fit (the lower
    /// one-step loss at the start).
    #[serde(default)]
    pub first_edge: Option<CarrierEdge>,
    /// Known dead time t_d \[s\]; `None`: estimated.
    #[serde(default)]
    pub t_d: Option<f64>,
    /// Known device threshold voltage u_th \[V\]; `None`: estimated.
    #[serde(default)]
    pub u_th: Option<f64>,
    /// Known width i_w \[A\] of the smooth leg state `(2/π) atan(i/i_w)`; `None`: the sign
    /// (unless `estimate_i_w`).
    #[serde(default)]
    pub i_w: Option<f64>,
    /// Estimate the leg-state width i_w (a parameter after `u_th`).
    #[serde(default)]
    pub estimate_i_w: bool,
    /// Device on-resistance r_on \[Ω\], in series with the winding.
    #[serde(default)]
    pub r_on: f64,
    /// Gain k_o of the one-step predictor's correction by the measured current (1: restart
    /// from the measurement every period, the default; 0: simulation, output error);
    /// `None`: estimated as a nuisance parameter (for logs with current noise).
    #[serde(default = "one")]
    pub predictor_gain: Option<f64>,
    /// Whether the fit searches the bandwidth of the controller's phase-locked loop
    /// (`--speed-pll estimate`): after the continuation, by the one-step loss over
    /// [`crate::pmsm::thresholds::SPEED_PLL_RANGE`] and against the logged angle and speed.
    #[serde(default)]
    pub search_speed_pll: bool,
}

fn one() -> Option<f64> {
    Some(1.0)
}

impl Default for PwmInverter {
    fn default() -> Self {
        Self {
            u_dc: None,
            carrier_hz: None,
            modulator: Modulator::MinMax,
            update: PwmUpdate::Double,
            levels: None,
            first_edge: None,
            t_d: None,
            u_th: None,
            i_w: None,
            estimate_i_w: false,
            r_on: 0.0,
            predictor_gain: one(),
            search_speed_pll: false,
        }
    }
}

impl PwmInverter {
    /// The nuisance parameters this inverter adds after the motor's: `t_d` \[s\] and `u_th`
    /// \[V\] (fixed when known), `i_w` \[A\] when estimated, the predictor gain `k_o` \[1\]
    /// when estimated; in the order of [`parameter_names`](Self::parameter_names).
    pub fn parameters(&self) -> Vec<Parameter> {
        self.parameter_names()
            .into_iter()
            .map(|name| match name {
                "t_d" => Parameter {
                    lower: 0.0,
                    nuisance: true,
                    fixed: self.t_d.is_some(),
                    ..Parameter::free("t_d", "s", 1e-6)
                },
                "u_th" => Parameter {
                    lower: 0.0,
                    nuisance: true,
                    fixed: self.u_th.is_some(),
                    ..Parameter::free("u_th", "V", 1.0)
                },
                "i_w" => Parameter { nuisance: true, ..Parameter::positive("i_w", "A", 0.1) },
                _ => Parameter { lower: 0.0, upper: 2.0, nuisance: true, ..Parameter::free("k_o", "1", 1.0) },
            })
            .collect()
    }

    /// Names of the nuisance parameters, in θ's order after the motor's: `t_d`, `u_th`, then
    /// `i_w` and `k_o` when estimated. The one list [`parameters`](Self::parameters) and
    /// [`start`](Self::start) follow.
    pub fn parameter_names(&self) -> Vec<&'static str> {
        let mut n = vec!["t_d", "u_th"];
        if self.estimate_i_w {
            n.push("i_w");
        }
        if self.predictor_gain.is_none() {
            n.push("k_o");
        }
        n
    }

    /// The start of the nuisance parameters from the averaged model's `v_dt` \[V\] at
    /// carrier frequency `f_sw` \[Hz\] and DC link `u_dc` \[V\] (`V_dt ≈ t_d f_sw U_dc + u_th`,
    /// MODEL.md §4), the known values kept: a fifth of `v_dt` to the devices (at most 1 V).
    pub fn start(&self, v_dt: f64, f_sw: f64, u_dc: f64) -> Vec<f64> {
        let v_dt = if v_dt.is_finite() && v_dt > 0.0 { v_dt } else { 1.0 };
        let u_th = self.u_th.unwrap_or((0.2 * v_dt).min(1.0));
        let t_d = self.t_d.unwrap_or(((v_dt - u_th).max(0.1 * v_dt) / (f_sw * u_dc)).max(1e-8));
        self.parameter_names()
            .into_iter()
            .map(|name| match name {
                "t_d" => t_d,
                "u_th" => u_th,
                "i_w" => self.i_w.unwrap_or(0.05),
                _ => PREDICTOR_GAIN_START,
            })
            .collect()
    }

    /// The DC-link voltage \[V\] at every sample of `e` (length N): the inverter's `u_dc`, or
    /// the log's column `u_dc`.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming `u_dc` when neither is given, or a value is not a
    /// positive, finite voltage (with its row).
    pub fn u_dc_samples(&self, e: &Experiment) -> Result<Vec<f64>> {
        let bad = |reason: String| Error::InvalidOption { option: "u_dc".into(), reason };
        match self.u_dc {
            Some(u) if u.is_finite() && u > 0.0 => Ok(vec![u; e.len()]),
            Some(u) => Err(bad(format!("{u} V is not a positive DC-link voltage"))),
            None => {
                let col = e.channel(U_DC).map_err(|_| {
                    bad("the PWM inverter needs the DC-link voltage: a column `u_dc` [V] or --u-dc".into())
                })?;
                match col.iter().position(|u| !(u.is_finite() && *u > 0.0)) {
                    Some(k) => Err(bad(format!(
                        "column `u_dc` row {k}: {} V is not a positive DC-link voltage",
                        col[k]
                    ))),
                    None => Ok(col.to_vec()),
                }
            }
        }
    }

    /// The carrier frequency \[Hz\] of a log of sample time `h` \[s\].
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming `carrier_hz` when a given one is not the one the
    /// sample time and update allow.
    pub fn carrier(&self, h: f64) -> Result<f64> {
        let f = match self.update {
            PwmUpdate::Double => 0.5 / h,
            PwmUpdate::Single => 1.0 / h,
        };
        match self.carrier_hz {
            Some(c) if c.is_nan() || (c - f).abs() > 1e-6 * f => Err(Error::InvalidOption {
                option: "carrier_hz".into(),
                reason: format!(
                    "{c} Hz, but a log sampled every {h:e} s at the carrier's {} has a {f} Hz carrier; give the \
                     sample time's carrier or the other update (--pwm-update)",
                    match self.update {
                        PwmUpdate::Double => "peaks and valleys (double update)",
                        PwmUpdate::Single => "peaks (single update)",
                    }
                ),
            }),
            _ => Ok(f),
        }
    }
}

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
    /// `theta_e` \[rad\], interval-mean mechanical speed `w_m` \[rad/s\], of the stator voltage
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
        u_ab: [f64; 2],
        u_dc: f64,
        h: f64,
    ) -> ([f64; 2], [f64; 2]) {
        let d = modulator::duty_ratios(inv, u_ab[0], u_ab[1], u_dc);
        let rising = self.k.is_multiple_of(2);
        self.k += 1;
        let per =
            Period::new(theta_e, w_e, w_m, u_dc, modulator::halves(inv, &mut self.carrier, d, rising, h));
        let [r, l_d, l_q, k_e] = motor;
        let [t_d, u_th, i_w] = inverter;
        let q = Params { r, l_d, l_q, k_e, t_d, u_th, i_w: (i_w > 0.0).then_some(i_w) };
        period::step_mean(&q, &per, i, h)
    }
}
