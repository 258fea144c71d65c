//! What a user asks of a simulated drive log, typed ([`SimulateRequest`]): the options of
//! `greybox simulate` and of the Python `simulate`, without their spelling and without the
//! files each writes; [`drive_config`] builds the drive's configuration from them, which
//! [`crate::drive::simulate_drive`] runs (thesis ch. 4).

use super::values::InverterChoice;
use crate::drive::{
    DriveConfig, IPM_MOTOR, IPM_SATURATION, SATURATED_IPM_MOTOR, SCENARIOS, SPM_MOTOR, scenario,
};
use crate::error::{Error, Result};
use serde_json::Value;
use std::path::PathBuf;

/// The motor of a thesis scenario: a small surface-magnet servo, an interior-magnet motor or
/// a saturating one ([`IPM_SATURATION`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Motor {
    /// [`SPM_MOTOR`].
    #[default]
    Spm,
    /// [`IPM_MOTOR`].
    Ipm,
    /// [`SATURATED_IPM_MOTOR`] with [`IPM_SATURATION`].
    IpmSat,
}

/// A simulation as asked for: the scenario (a thesis or commissioning one by name, or a
/// scenario file), its motor, seed and length, fields set by their paths, and the
/// switching-resolved inverter's settings. Units SI.
#[derive(Clone, Debug, PartialEq)]
pub struct SimulateRequest {
    /// A scenario by name (`exp1` … `exp6`, or a commissioning one).
    pub scenario: Option<String>,
    /// A scenario file (JSON, as `--print-config` writes it).
    pub config: Option<PathBuf>,
    /// The motor of a named scenario.
    pub motor: Motor,
    /// Seed of the sensor noise.
    pub seed: Option<u64>,
    /// Length of the record \[s\].
    pub duration: Option<f64>,
    /// Fields set by their paths in the scenario file, `PATH=VALUE` (the value JSON), in
    /// order.
    pub set: Vec<String>,
    /// The inverter: averaged (`None`) or switching-resolved (`Pwm`).
    pub inverter: InverterChoice,
    /// Dead time of the switching-resolved inverter \[s\].
    pub t_d: f64,
    /// Device threshold voltage of the switching-resolved inverter \[V\].
    pub u_th: f64,
    /// Width of its smooth leg state \[A\]; 0: the sign.
    pub leg_state_width: f64,
    /// Levels of its PWM counter; 0: continuous duty ratios.
    pub pwm_levels: u32,
}

impl Default for SimulateRequest {
    /// The command line's defaults (no scenario yet).
    fn default() -> Self {
        Self {
            scenario: None,
            config: None,
            motor: Motor::Spm,
            seed: None,
            duration: None,
            set: Vec::new(),
            inverter: InverterChoice::None,
            t_d: 2e-6,
            u_th: 1.0,
            leg_state_width: 0.0,
            pwm_levels: 0,
        }
    }
}

/// The drive's configuration of `r`: the scenario with its motor, the switching-resolved
/// inverter where asked, the seed, the length and every field set, validated.
///
/// # Errors
/// [`Error::InvalidOption`] naming `scenario` (none given, an unknown one), `config` (with a
/// scenario, an invalid file) or `set` ([`set_field`]); [`Error::Io`] for an unreadable
/// file; those of [`DriveConfig::validate`].
pub fn drive_config(r: &SimulateRequest) -> Result<DriveConfig> {
    let mut cfg = match (&r.scenario, &r.config) {
        (Some(_), Some(_)) => {
            return Err(Error::InvalidOption {
                option: "config".into(),
                reason: "not together with --scenario: give one of them".into(),
            });
        }
        (Some(name), None) => {
            let motor = match r.motor {
                Motor::Spm => SPM_MOTOR,
                Motor::Ipm => IPM_MOTOR,
                Motor::IpmSat => SATURATED_IPM_MOTOR,
            };
            let saturation = matches!(r.motor, Motor::IpmSat).then_some(IPM_SATURATION);
            DriveConfig { saturation, ..scenario(name, motor)? }
        }
        (None, Some(path)) => {
            let text =
                std::fs::read_to_string(path).map_err(|source| Error::Io { path: path.clone(), source })?;
            serde_json::from_str::<DriveConfig>(&text).map_err(|e| Error::InvalidOption {
                option: "config".into(),
                reason: format!("{}: {e}", path.display()),
            })?
        }
        (None, None) => {
            return Err(Error::InvalidOption {
                option: "scenario".into(),
                reason: format!(
                    "give --scenario ({}, {}) or --config FILE",
                    SCENARIOS.join(", "),
                    crate::drive::COMMISSIONING.join(", ")
                ),
            });
        }
    };
    if r.inverter == InverterChoice::Pwm {
        cfg.inverter.pwm = Some(crate::drive::PwmPlant {
            t_d: r.t_d,
            u_th: r.u_th,
            i_w: r.leg_state_width,
            levels: r.pwm_levels,
        });
    }
    if let Some(seed) = r.seed {
        cfg.seed = seed;
    }
    if let Some(d) = r.duration {
        cfg.duration = d;
    }
    for s in &r.set {
        cfg = set_field(&cfg, s)?;
    }
    cfg.validate()?;
    Ok(cfg)
}

/// The configuration with the field at the dotted `path` set to `value` (`PATH=VALUE`,
/// the value as JSON, e.g. a number, `null` or `[[0, 1], [2, 3]]`).
///
/// # Errors
/// [`Error::InvalidOption`] (`set`) for text without `=`, a value that is not JSON, a path
/// that is not a field (naming the fields there), a value of the wrong type.
pub fn set_field(cfg: &DriveConfig, assignment: &str) -> Result<DriveConfig> {
    let bad = |reason: String| Error::InvalidOption { option: "set".into(), reason };
    let (path, value) =
        assignment.split_once('=').ok_or_else(|| bad(format!("`{assignment}`: expected PATH=VALUE")))?;
    let value: Value = serde_json::from_str(value.trim())
        .map_err(|e| bad(format!("`{assignment}`: the value is not JSON: {e}")))?;
    let mut root = serde_json::to_value(cfg).map_err(|e| bad(e.to_string()))?;
    let pointer = format!("/{}", path.trim().replace('.', "/"));
    let Some(slot) = root.pointer_mut(&pointer) else {
        // Name the fields where the path stops matching: the deepest object along it.
        let parts: Vec<&str> = path.trim().split('.').collect();
        let mut at = &serde_json::to_value(cfg).map_err(|e| bad(e.to_string()))?;
        let mut prefix = Vec::new();
        for part in &parts {
            match at.get(part) {
                Some(next) if next.is_object() => {
                    at = next;
                    prefix.push(*part);
                }
                _ => break,
            }
        }
        let fields: Vec<String> = at
            .as_object()
            .map(|o| {
                o.keys()
                    .map(|k| prefix.iter().chain([&k.as_str()]).copied().collect::<Vec<_>>().join("."))
                    .collect()
            })
            .unwrap_or_default();
        return Err(bad(format!(
            "`{path}` is not a field of the scenario; the fields there are: {} (all of them: --print-config)",
            fields.join(", ")
        )));
    };
    *slot = value;
    serde_json::from_value(root).map_err(|e| bad(format!("`{assignment}`: {e}")))
}
