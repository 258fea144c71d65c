//! The plan language of `greybox design` (issue 32): the design knobs of a planned drive
//! experiment — d-current injection (amplitude, pulse length), speed levels, record length
//! — applied to a base [`DriveConfig`], the named planned injections, and the check that a
//! plan stays within the drive's current and voltage limits.
//!
//! The thesis leaves the injection open (section 5.1.1: "a short d-current injection");
//! its scenarios are in [`super::scenario()`] (thesis ch. 6). A plan whose controller
//! clamps its current or voltage reference is not the plan the prediction assumed (the
//! drive would not follow the references), so the search rejects it.

use super::config::DriveConfig;
use super::profile::Profile;
use super::scenario::{SCENARIOS, scenario};
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::MotorParameters;
use serde::{Deserialize, Serialize};

/// The planned injections beyond the thesis' scenarios, by name: exp3 with a constant d
/// current of `−0.5 i_max` over the whole record (`exp3_id_const`), and exp3 with
/// `−0.7 i_max` pulses of 0.2 s every 0.4 s from 0.3 s (`exp3_id_pulses`); both replace
/// exp3's single injection and stay within its current limit (peaks 0.71 and 0.86 i_max).
pub const PLANS: [&str; 2] = ["exp3_id_const", "exp3_id_pulses"];

/// Horizon \[s\] up to which a named plan's injection pulses are laid out (a longer record
/// has no pulses after it; [`Knobs::apply`] lays them out over the plan's own duration).
const NAMED_HORIZON: f64 = 120.0;

/// A d-current injection: the reference `i_d = −amplitude · i_max` \[A\], constant or in
/// pulses. Plain data.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Injection {
    /// Amplitude as a fraction of the current limit `i_max` (in \[0, 1); 0: `i_d = 0`).
    pub amplitude: f64,
    /// Pulse length \[s\]; `None`: constant over the record.
    pub pulse: Option<f64>,
    /// Time between the starts of two pulses \[s\].
    pub period: f64,
    /// Start of the first pulse \[s\].
    pub start: f64,
}

impl Injection {
    /// A constant injection of `amplitude` (fraction of `i_max`).
    pub fn constant(amplitude: f64) -> Self {
        Self { amplitude, pulse: None, period: 1.0, start: 0.0 }
    }

    /// The d-current reference profile \[A\] up to `horizon` \[s\] for the current limit
    /// `i_max` \[A\].
    pub fn profile(&self, i_max: f64, horizon: f64) -> Profile {
        let level = -self.amplitude * i_max;
        match self.pulse {
            None => Profile::constant(level),
            Some(width) => {
                let mut p = vec![(0.0, 0.0)];
                let mut s = self.start;
                while s < horizon {
                    p.extend([(s, 0.0), (s, level), (s + width, level), (s + width, 0.0)]);
                    s += self.period.max(width);
                }
                Profile(p)
            }
        }
    }

    /// A short label, e.g. `id -0.2 imax` or `id -0.3 imax 0.2 s/0.8 s`.
    pub fn label(&self) -> String {
        match self.pulse {
            _ if self.amplitude == 0.0 => "id 0".into(),
            None => format!("id -{} imax", self.amplitude),
            Some(w) => format!("id -{} imax {w} s/{} s", self.amplitude, self.period),
        }
    }

    /// Checks the values.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (`injection`) for an amplitude outside \[0, 1), a
    /// non-positive pulse length or period, a negative start.
    pub fn validate(&self) -> Result<()> {
        let bad = |reason: String| Error::InvalidOption { option: "injection".into(), reason };
        if !(0.0..1.0).contains(&self.amplitude) {
            return Err(bad(format!("amplitude {} is outside [0, 1) (a fraction of i_max)", self.amplitude)));
        }
        if self.pulse.is_some_and(|w| !(w.is_finite() && w > 0.0))
            || !(self.period.is_finite() && self.period > 0.0)
        {
            return Err(bad(format!(
                "pulse {:?} s and period {} s must be positive",
                self.pulse, self.period
            )));
        }
        if !(self.start.is_finite() && self.start >= 0.0) {
            return Err(bad(format!("start {} s must be non-negative", self.start)));
        }
        Ok(())
    }
}

/// The design knobs of one candidate plan, applied to a base plan by [`Knobs::apply`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Knobs {
    /// The d-current injection replacing the base plan's; `None`: the base plan's own.
    pub injection: Option<Injection>,
    /// Factor on the reference profile's values (speed mode: the speed levels; position
    /// mode: the distances at the same times, so the speeds too) \[-\].
    pub speed_scale: f64,
    /// Record length \[s\].
    pub duration: f64,
}

impl Knobs {
    /// The base plan `base` with these knobs: record length, scaled reference, injection
    /// (pulses laid out over the record). Named `BASE [knob labels] T s`.
    pub fn apply(&self, base: &DriveConfig) -> DriveConfig {
        let mut cfg = base.clone();
        cfg.duration = self.duration;
        if self.speed_scale != 1.0 {
            cfg.control.reference =
                Profile(base.control.reference.0.iter().map(|&(t, v)| (t, v * self.speed_scale)).collect());
        }
        if let Some(inj) = &self.injection {
            cfg.control.i_d = inj.profile(cfg.control.i_max, self.duration);
        }
        cfg.name = self.label(&base.name);
        cfg
    }

    /// The candidate's name on the base plan `base`.
    pub fn label(&self, base: &str) -> String {
        let mut s = base.to_string();
        if let Some(inj) = &self.injection {
            s += &format!(" {}", inj.label());
        }
        if self.speed_scale != 1.0 {
            s += &format!(" speed x{}", self.speed_scale);
        }
        s + &format!(" {} s", self.duration)
    }
}

/// The drive of a thesis scenario ([`SCENARIOS`]) or of a named planned injection
/// ([`PLANS`]) on `motor`.
///
/// # Errors
/// [`Error::InvalidOption`] (`scenario`) for an unknown name, listing the known ones.
pub fn planned_drive(name: &str, motor: MotorParameters) -> Result<DriveConfig> {
    let injection = match name {
        "exp3_id_const" => Injection::constant(0.5),
        "exp3_id_pulses" => Injection { amplitude: 0.7, pulse: Some(0.2), period: 0.4, start: 0.3 },
        _ if SCENARIOS.contains(&name) => return scenario(name, motor),
        _ => {
            return Err(Error::InvalidOption {
                option: "scenario".into(),
                reason: format!("`{name}` is not one of {}, {}", SCENARIOS.join(", "), PLANS.join(", ")),
            });
        }
    };
    let mut cfg = scenario("exp3", motor)?;
    cfg.control.i_d = injection.profile(cfg.control.i_max, NAMED_HORIZON);
    cfg.name = name.into();
    Ok(cfg)
}

/// How much of the drive's limits a (noise-free) run of `cfg` uses: the largest current
/// reference `|i_ref|/i_max` and voltage reference `|u_ref|/(U_dc/√3)` of the log.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LimitUse {
    /// Peak current reference over the current limit \[-\] (1: the limit clamped it).
    pub current: f64,
    /// Peak voltage reference over the voltage limit \[-\] (1: the limit clamped it).
    pub voltage: f64,
}

/// Within this of 1 a reference counts as clamped by its limit (the clamp sets it to the
/// limit to rounding).
const CLAMPED: f64 = 1e-6;

impl LimitUse {
    /// The peaks of the log `log` (channels `id_ref, iq_ref, ud_ref, uq_ref`, as
    /// [`super::simulate_drive`] writes them) of the drive `cfg`.
    ///
    /// # Errors
    /// [`Error::MissingChannel`] for a log without the reference channels.
    pub fn of(log: &Experiment, cfg: &DriveConfig) -> Result<Self> {
        let peak = |a: &str, b: &str| -> Result<f64> {
            let (x, y) = (log.channel(a)?, log.channel(b)?);
            Ok(x.iter().zip(y).map(|(x, y)| x.hypot(*y)).fold(0.0, f64::max))
        };
        let u_max = cfg.control.u_dc / 3f64.sqrt();
        Ok(Self {
            current: peak("id_ref", "iq_ref")? / cfg.control.i_max,
            voltage: peak("ud_ref", "uq_ref")? / u_max,
        })
    }

    /// Which limit the run reached, if any (`"current limit"`, `"voltage limit"`).
    pub fn reached(&self) -> Option<String> {
        let hit = |v: f64| v >= 1.0 - CLAMPED;
        match (hit(self.current), hit(self.voltage)) {
            (false, false) => None,
            (true, false) => Some("reaches the current limit".into()),
            (false, true) => Some("reaches the voltage limit".into()),
            (true, true) => Some("reaches the current and voltage limits".into()),
        }
    }
}

/// The knob grid of a design search: every combination of injection, speed scale and
/// record length (the injections: the base plan's own, then each amplitude constant and
/// in pulses of each length; a zero amplitude only once, as `i_d = 0`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    /// Injection amplitudes \[fraction of i_max\].
    pub amplitudes: Vec<f64>,
    /// Pulse lengths \[s\]; 0 stands for a constant injection.
    pub pulses: Vec<f64>,
    /// Time between pulse starts \[s\] (at least the pulse length).
    pub period: f64,
    /// Speed scales \[-\].
    pub speed_scales: Vec<f64>,
    /// Record lengths \[s\].
    pub durations: Vec<f64>,
}

impl Default for Grid {
    fn default() -> Self {
        Self {
            amplitudes: vec![0.0, 0.2, 0.5],
            pulses: vec![0.0, 0.2],
            period: 0.4,
            speed_scales: vec![0.5, 1.0, 1.5],
            durations: vec![0.5, 1.0, 2.0, 4.0, 8.0],
        }
    }
}

impl Grid {
    /// Every knob combination, in the order injection × speed scale × duration.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (`injection`, `speed-scales`, `durations`) for an invalid
    /// amplitude, pulse, period, a non-positive speed scale or record length, or an empty
    /// list.
    pub fn candidates(&self) -> Result<Vec<Knobs>> {
        let bad = |option: &str, reason: &str| Error::InvalidOption {
            option: option.into(),
            reason: reason.into(),
        };
        if self.speed_scales.is_empty() || self.speed_scales.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(bad("speed-scales", "give positive speed scales"));
        }
        if self.durations.is_empty() || self.durations.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(bad("durations", "give positive record lengths [s]"));
        }
        let mut injections = vec![None];
        for &amplitude in &self.amplitudes {
            for &pulse in &self.pulses {
                let pulse = (pulse != 0.0 && amplitude != 0.0).then_some(pulse);
                let inj =
                    Injection { amplitude, pulse, period: self.period.max(pulse.unwrap_or(0.0)), start: 0.3 };
                inj.validate()?;
                if !injections.contains(&Some(inj)) {
                    injections.push(Some(inj));
                }
            }
        }
        Ok(injections
            .iter()
            .flat_map(|&injection| {
                self.speed_scales.iter().flat_map(move |&speed_scale| {
                    self.durations.iter().map(move |&duration| Knobs { injection, speed_scale, duration })
                })
            })
            .collect())
    }
}
