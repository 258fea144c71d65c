//! The flags of the switching-resolved PWM inverter (`--inverter pwm`) and their conversion
//! into the library's [`PwmInverter`].

use crate::error::{Error, Result};
use crate::pmsm::{CarrierEdge, Modulator, PwmInverter, PwmUpdate};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// Which inverter sits between the voltage reference and the motor (`--inverter`).
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum InverterArg {
    #[default]
    None,
    Pwm,
}

/// The PWM inverter's flags, shared by `fit` and `simulate`.
#[derive(Args, Debug, Clone, Default)]
pub struct PwmArgs {
    /// The inverter between the voltage reference and the motor: none (the reference is the
    /// motor's voltage, or the averaged --dead-time model), or pwm: switching-resolved
    /// (modulator, carrier, dead time t_d and device threshold u_th estimated with the
    /// motor, the phase currents' direction inside each period from the model); needs
    /// --voltage reference, theta_m and the DC link (--u-dc or a column u_dc).
    #[arg(help_heading = "Inverter and cable", long, value_enum, default_value_t = InverterArg::None)]
    pub inverter: InverterArg,
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
    #[arg(help_heading = "Inverter and cable", long, value_parser = parse_leg_width)]
    pub leg_state_width: Option<LegWidth>,
    /// Gain k_o of the PWM model's one-step predictor (with --inverter pwm): 1 restarts every
    /// period from the measured current (the default), lower values trust the model more
    /// (for noisy currents), `estimate` fits it as a nuisance parameter.
    #[arg(help_heading = "Inverter and cable", long, value_parser = parse_gain)]
    pub predictor_gain: Option<Gain>,
    /// The inverter's known parameters from a JSON file: keys t_d [s], u_th [V], r_on [Ω],
    /// i_w [A] (a datasheet), or a fit report of --inverter pwm (its `parameters`); the
    /// ones given are held fixed.
    #[arg(help_heading = "Inverter and cable", long)]
    pub inverter_params: Option<PathBuf>,
}

/// A leg-state width in amperes or `estimate`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LegWidth {
    /// Known width \[A\].
    Amperes(f64),
    /// Estimated with the motor's parameters.
    Estimate,
    /// The hard sign.
    Sign,
}

/// A predictor gain, or `estimate`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Gain {
    /// Known gain.
    Value(f64),
    /// Estimated.
    Estimate,
}

fn parse_gain(s: &str) -> std::result::Result<Gain, String> {
    match s {
        "estimate" => Ok(Gain::Estimate),
        _ => match s.parse::<f64>() {
            Ok(g) if (0.0..=2.0).contains(&g) => Ok(Gain::Value(g)),
            _ => Err(format!("`{s}`: expected a gain in [0, 2] or `estimate`")),
        },
    }
}

fn parse_leg_width(s: &str) -> std::result::Result<LegWidth, String> {
    match s {
        "estimate" => Ok(LegWidth::Estimate),
        "sign" => Ok(LegWidth::Sign),
        _ => match s.parse::<f64>() {
            Ok(w) if w.is_finite() && w > 0.0 => Ok(LegWidth::Amperes(w)),
            _ => Err(format!("`{s}`: expected a positive width in A, `estimate` or `sign`")),
        },
    }
}

impl PwmArgs {
    /// The inverter these flags describe at DC link `u_dc` \[V\] (`None`: a column `u_dc`);
    /// `None` without `--inverter pwm`.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming the PWM flag given without `--inverter pwm`, or an
    /// unreadable `--inverter-params` file or key.
    pub fn inverter(&self, u_dc: Option<f64>) -> Result<Option<PwmInverter>> {
        if self.inverter == InverterArg::None {
            let stray = [
                ("--carrier-hz", self.carrier_hz.is_some()),
                ("--pwm-levels", self.pwm_levels.is_some()),
                ("--carrier-first", self.carrier_first.is_some()),
                ("--leg-state-width", self.leg_state_width.is_some()),
                ("--inverter-params", self.inverter_params.is_some()),
                ("--predictor-gain", self.predictor_gain.is_some()),
                ("--modulator", self.modulator != Modulator::MinMax),
                ("--pwm-update", self.pwm_update != PwmUpdate::Double),
            ];
            if let Some((flag, _)) = stray.iter().find(|(_, given)| *given) {
                return Err(Error::InvalidOption {
                    option: flag.trim_start_matches('-').into(),
                    reason: format!("{flag} describes the PWM inverter: add --inverter pwm"),
                });
            }
            return Ok(None);
        }
        let mut inv = PwmInverter {
            u_dc,
            carrier_hz: self.carrier_hz,
            modulator: self.modulator,
            update: self.pwm_update,
            levels: self.pwm_levels,
            first_edge: self.carrier_first,
            predictor_gain: match self.predictor_gain {
                Some(Gain::Value(g)) => Some(g),
                Some(Gain::Estimate) => None,
                None => Some(1.0),
            },
            ..PwmInverter::default()
        };
        match self.leg_state_width {
            Some(LegWidth::Amperes(w)) => inv.i_w = Some(w),
            Some(LegWidth::Estimate) | None => inv.estimate_i_w = true,
            Some(LegWidth::Sign) => {}
        }
        if let Some(path) = &self.inverter_params {
            known_parameters(path, &mut inv)?;
        }
        Ok(Some(inv))
    }
}

/// Reads the known inverter parameters of `path` into `inv`.
fn known_parameters(path: &PathBuf, inv: &mut PwmInverter) -> Result<()> {
    let bad = |reason: String| Error::InvalidOption { option: "inverter-params".into(), reason };
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("{}: {e}", path.display())))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(format!("{}: not JSON ({e})", path.display())))?;
    let value = |key: &str| -> Option<f64> {
        json.get(key).and_then(serde_json::Value::as_f64).or_else(|| {
            json.get("parameters")?
                .as_array()?
                .iter()
                .find(|p| p.get("name").and_then(|n| n.as_str()) == Some(key))?
                .get("value")?
                .as_f64()
        })
    };
    let mut found = 0;
    for (key, slot) in [("t_d", &mut inv.t_d), ("u_th", &mut inv.u_th), ("i_w", &mut inv.i_w)] {
        if let Some(v) = value(key) {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(format!("{}: {key} = {v} must be finite and not negative", path.display())));
            }
            *slot = Some(v);
            found += 1;
        }
    }
    if inv.i_w.is_some() {
        inv.estimate_i_w = false;
    }
    if let Some(r) = value("r_on") {
        if !(r.is_finite() && r >= 0.0) {
            return Err(bad(format!("{}: r_on = {r} must be finite and not negative", path.display())));
        }
        inv.r_on = r;
        found += 1;
    }
    if found == 0 {
        return Err(bad(format!(
            "{}: none of t_d [s], u_th [V], r_on [Ω], i_w [A] found (as keys or in `parameters`)",
            path.display()
        )));
    }
    Ok(())
}
