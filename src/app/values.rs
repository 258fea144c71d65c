//! The typed values of a fit's options that are more than a number: a pole-pair count or
//! `auto`, a delay or `estimate`, the method, the voltage, the model; each parsed from the
//! words the command line and the Python keywords share (`FromStr`, [`super::Choice`]).

use crate::estimate::weighting::{SpeedShape, SpeedWeighting};
use crate::estimate::{PrecisionTarget, WeightingKind};
use crate::pmsm::{DeadTimeMask, Dynamics, MotorKind};
use std::str::FromStr;

/// A pole-pair number, or to be chosen from the data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PolePairs {
    /// This many pole pairs.
    Given(u32),
    /// Chosen by the lowest loss.
    Auto,
}

impl FromStr for PolePairs {
    type Err = String;
    /// `auto` or a whole number.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            _ => s.parse().map(Self::Given).map_err(|_| format!("`{s}`: expected auto or a whole number")),
        }
    }
}

/// A delay in samples, or to be estimated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delay {
    /// This many samples.
    Samples(usize),
    /// Searched by the lowest loss.
    Estimate,
}

impl FromStr for Delay {
    type Err = String;
    /// `N` or `estimate`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "estimate" => Ok(Self::Estimate),
            _ => s
                .parse()
                .map(Self::Samples)
                .map_err(|_| format!("`{s}`: expected a number of samples or `estimate`")),
        }
    }
}

/// A modulator angle advance \[ω_e h\], or to be estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Advance {
    /// This advance \[ω_e h\].
    Value(f64),
    /// Searched by the lowest loss.
    Estimate,
}

impl FromStr for Advance {
    type Err = String;
    /// A finite advance or `estimate`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "estimate" => Ok(Self::Estimate),
            _ => s
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .map(Self::Value)
                .ok_or_else(|| format!("`{s}`: expected estimate or a number (units of ω_e h)")),
        }
    }
}

/// The averaged dead-time model: off, estimated, or known \[V\].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DeadTime {
    /// No inverter model.
    None,
    /// The voltage estimated as a nuisance parameter.
    Estimate,
    /// A known voltage \[V\].
    Volts(f64),
}

impl FromStr for DeadTime {
    type Err = String;
    /// `none`, `estimate` or a voltage ≥ 0.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "none" => Ok(Self::None),
            "estimate" => Ok(Self::Estimate),
            _ => s
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && *v >= 0.0)
                .map(Self::Volts)
                .ok_or_else(|| format!("`{s}`: expected none, estimate or a voltage ≥ 0")),
        }
    }
}

/// A positive value (a speed-estimator bandwidth \[rad/s\], a sign width \[A\], a Coulomb
/// speed \[rad/s\]), or to be estimated, or (a speed estimator only) the logged speed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pll {
    /// This value (bandwidth \[rad/s\] or width \[A\]).
    Bandwidth(f64),
    /// Searched by the lowest loss.
    Estimate,
    /// None: the logged speed (`--speed-pll logged`).
    Logged,
}

impl FromStr for Pll {
    type Err = String;
    /// A positive bandwidth, `estimate` or `logged`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "estimate" => Ok(Self::Estimate),
            "logged" => Ok(Self::Logged),
            _ => s.parse().ok().filter(|a: &f64| a.is_finite() && *a > 0.0).map(Self::Bandwidth).ok_or_else(
                || format!("`{s}`: expected a positive bandwidth in rad/s, `estimate` or `logged`"),
            ),
        }
    }
}

impl Pll {
    /// A positive value or `estimate` (not `logged`), naming `what` it expected in the
    /// error (e.g. `a positive width in A`).
    ///
    /// # Errors
    /// A message quoting `s`.
    pub fn positive_or_estimate(s: &str, what: &str) -> Result<Self, String> {
        s.parse::<Self>()
            .ok()
            .filter(|p| *p != Self::Logged)
            .ok_or_else(|| format!("`{s}`: expected {what} or `estimate`"))
    }

    /// A sign width \[A\] or `estimate` (`--dead-time-width`).
    ///
    /// # Errors
    /// A message quoting `s`.
    pub fn width(s: &str) -> Result<Self, String> {
        Self::positive_or_estimate(s, "a positive width in A")
    }
}

/// A dead-time mask: `auto` or a current ≥ 0 \[A\].
///
/// # Errors
/// A message quoting `s`.
pub fn parse_mask(s: &str) -> Result<DeadTimeMask, String> {
    match s {
        "auto" => Ok(DeadTimeMask::Auto),
        _ => s
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v >= 0.0)
            .map(DeadTimeMask::Current)
            .ok_or_else(|| format!("`{s}`: expected auto or a current ≥ 0 in amperes")),
    }
}

/// A parameter held fixed: `NAME` (at its start value) or `NAME=VALUE` (a finite value).
///
/// # Errors
/// A message quoting `s`.
pub fn parse_fix(s: &str) -> Result<(String, Option<f64>), String> {
    match s.split_once('=') {
        None if !s.is_empty() => Ok((s.to_string(), None)),
        None => Err("empty parameter name".into()),
        Some((name, v)) => {
            let v: f64 = v.parse().map_err(|e| format!("`{s}`: {e}; expected NAME or NAME=VALUE"))?;
            if name.is_empty() || !v.is_finite() {
                return Err(format!("`{s}`: expected NAME or NAME=VALUE with a finite value"));
            }
            Ok((name.to_string(), Some(v)))
        }
    }
}

/// A parameter's bounds, `NAME:LO:HI`.
///
/// # Errors
/// A message quoting `s`.
pub fn parse_bounds(s: &str) -> Result<(String, f64, f64), String> {
    let parts: Vec<&str> = s.split(':').collect();
    let [name, lo, hi] = parts[..] else { return Err(format!("`{s}`: expected NAME:LO:HI")) };
    let num = |v: &str| v.parse::<f64>().map_err(|e| format!("`{s}`: {e}"));
    Ok((name.to_string(), num(lo)?, num(hi)?))
}

/// The accuracy a trusted fit must reach ([`crate::estimate::imprecise`]): `off` (none), or
/// `NAME=X%[,NAME=X%…]`, each a parameter and its largest relative three-standard-error
/// half width in percent (`r_s=0.5%,k_e=0.05%`; a value without `%` is a fraction).
///
/// # Errors
/// A message quoting `s`: an empty name, a value that is not a positive finite number.
pub fn parse_precision(s: &str) -> Result<Vec<PrecisionTarget>, String> {
    if s == "off" {
        return Ok(Vec::new());
    }
    s.split(',')
        .map(|item| {
            let bad = || format!("`{item}`: expected off or NAME=X% (e.g. r_s=0.5%,k_e=0.05%)");
            let (name, value) = item.split_once('=').map(|(n, v)| (n.trim(), v.trim())).ok_or_else(bad)?;
            if name.is_empty() {
                return Err(bad());
            }
            let relative = match value.strip_suffix('%') {
                Some(p) => p.trim().parse::<f64>().map(|p| p / 100.0),
                None => value.parse::<f64>(),
            }
            .ok()
            .filter(|r| r.is_finite() && *r > 0.0)
            .ok_or_else(bad)?;
            Ok(PrecisionTarget { parameter: name.to_string(), relative })
        })
        .collect()
}

/// A sample weighting β(ω) (thesis eq. 5.11) on the mechanical speed: `uniform`,
/// `low-speed:W0`, `high-speed:W0`, `band:LO:HI[:FLOOR]` (rad/s).
///
/// # Errors
/// A message quoting `s`, or the weighting's own check's.
pub fn parse_weighting(s: &str) -> Result<WeightingKind, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let num = |i: usize| -> Result<f64, String> {
        parts
            .get(i)
            .ok_or_else(|| format!("`{s}`: missing number {i}"))?
            .parse::<f64>()
            .map_err(|e| format!("`{s}`: {e}"))
    };
    let shape = match parts[0] {
        "uniform" if parts.len() == 1 => return Ok(WeightingKind::Uniform),
        "low-speed" if parts.len() == 2 => SpeedShape::LowSpeed { w0: num(1)? },
        "high-speed" if parts.len() == 2 => SpeedShape::HighSpeed { w0: num(1)? },
        "band" if parts.len() == 3 || parts.len() == 4 => {
            SpeedShape::Band { lo: num(1)?, hi: num(2)?, floor: if parts.len() == 4 { num(3)? } else { 0.0 } }
        }
        _ => {
            return Err(format!(
                "`{s}`: expected uniform, low-speed:W0, high-speed:W0 or band:LO:HI[:FLOOR]"
            ));
        }
    };
    let channel = crate::pmsm::channel::W_M;
    SpeedWeighting::try_new(channel, shape).map_err(|e| e.to_string())?;
    Ok(WeightingKind::Speed { channel: channel.into(), shape })
}

/// The estimation method: prediction error, or instrumental variables where the logged
/// voltage's noise biases it (`auto`), prediction error (`pem`), linear least squares
/// (`ls`), instrumental variables (`iv`).
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Method {
    #[default]
    Auto,
    Pem,
    Ls,
    Iv,
}

/// Which voltage drives the model: the measured terminal voltage (`actual`) or the
/// controller's reference (`reference`).
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Voltage {
    #[default]
    Actual,
    Reference,
}

/// The machine model and its equations: surface or interior magnets, dynamic (chosen from
/// the sample time) or the steady-state equations of slow logs.
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ModelChoice {
    #[default]
    Spm,
    Ipm,
    SpmSteady,
    IpmSteady,
}

impl ModelChoice {
    /// The machine.
    pub fn kind(self) -> MotorKind {
        match self {
            Self::Spm | Self::SpmSteady => MotorKind::Spm,
            Self::Ipm | Self::IpmSteady => MotorKind::Ipm,
        }
    }

    /// Which equations: chosen from the sample time, or the steady-state ones.
    pub fn dynamics(self) -> Dynamics {
        match self {
            Self::Spm | Self::Ipm => Dynamics::Auto,
            Self::SpmSteady | Self::IpmSteady => Dynamics::Steady,
        }
    }
}

/// Which inverter sits between the voltage reference and the motor: none, or the
/// switching-resolved PWM inverter.
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InverterChoice {
    #[default]
    None,
    Pwm,
}

/// A leg-state width in amperes, `estimate` or `sign`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LegWidth {
    /// Known width \[A\].
    Amperes(f64),
    /// Estimated with the motor's parameters.
    Estimate,
    /// The hard sign.
    Sign,
}

impl FromStr for LegWidth {
    type Err = String;
    /// A positive width \[A\], `estimate` or `sign`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "estimate" => Ok(Self::Estimate),
            "sign" => Ok(Self::Sign),
            _ => match s.parse::<f64>() {
                Ok(w) if w.is_finite() && w > 0.0 => Ok(Self::Amperes(w)),
                _ => Err(format!("`{s}`: expected a positive width in A, `estimate` or `sign`")),
            },
        }
    }
}

/// A predictor gain, or `estimate`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Gain {
    /// Known gain.
    Value(f64),
    /// Estimated.
    Estimate,
}

impl FromStr for Gain {
    type Err = String;
    /// A gain in \[0, 2\] or `estimate`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "estimate" => Ok(Self::Estimate),
            _ => match s.parse::<f64>() {
                Ok(g) if (0.0..=2.0).contains(&g) => Ok(Self::Value(g)),
                _ => Err(format!("`{s}`: expected a gain in [0, 2] or `estimate`")),
            },
        }
    }
}
