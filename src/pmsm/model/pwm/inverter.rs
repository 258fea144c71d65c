//! The PWM inverter's settings and parameters: modulator, carrier update and edge, DC
//! link, dead time, threshold, leg-state width and the predictor's gain.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::Parameter;
use serde::{Deserialize, Serialize};

/// Start of the estimated predictor gain k_o: the restart from the measured current, the
/// gain of the default fit.
const PREDICTOR_GAIN_START: f64 = 1.0;

/// The DC-link voltage column a log may carry \[V\].
const U_DC: &str = "u_dc";

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
