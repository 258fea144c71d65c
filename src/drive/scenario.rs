//! The thesis' simulated experiments as ready-made drives (thesis ch. 5–6, MODEL.md §7):
//! `exp1` MRAS validation, `exp2` a position step with `K_t` 20 % too high in the
//! controller, `exp3` back-and-forth moves at increasing speeds, `exp4` a warm motor,
//! `exp5` low acceleration, `exp6` a material-handling cycle with a d-current injection
//! every few seconds. Each scales to the motor it is given (torques from `K_t i_max`).

use super::config::{DriveConfig, Mode};
use super::profile::Profile;
use crate::error::{Error, Result};
use crate::pmsm::MotorParameters;

/// The scenario names, in order.
pub const SCENARIOS: [&str; 6] = ["exp1", "exp2", "exp3", "exp4", "exp5", "exp6"];

/// Commissioning scenarios (not thesis experiments; [`scenario`] builds them too):
/// `standstill`, a locked-rotor test as drive firmware runs at power-up.
pub const COMMISSIONING: [&str; 1] = ["standstill"];

/// The drive of scenario `name` (one of [`SCENARIOS`] or [`COMMISSIONING`]) on `motor`.
///
/// # Errors
/// [`Error::InvalidOption`] (`scenario`) for an unknown name, listing the known ones.
pub fn scenario(name: &str, motor: MotorParameters) -> Result<DriveConfig> {
    let base = DriveConfig { name: name.into(), motor, ..Default::default() };
    let t_max = motor.k_t() * base.control.i_max;
    let c = base.control.clone();
    Ok(match name {
        // Thesis Exp 1 (MODEL.md §7): a torque step at 1 s on a speed-proportional load; the
        // plant's K_t ramps down 10 % from 5 s to 7 s and its R_s up 20 % from 9 s to 11 s;
        // i_d reference 20 % of i_q's; sample time 0.126 ms; 16 s, so that the estimates
        // settle after the last ramp.
        "exp1" => DriveConfig {
            control: super::config::Control {
                h: 0.126e-3,
                mode: Mode::Torque,
                reference: Profile(vec![(0.0, 0.0), (1.0, 0.0), (1.0, 0.5 * t_max)]),
                i_d_ratio: 0.2,
                ..c
            },
            mechanics: super::config::Mechanics { viscous: 0.5 * t_max / 150.0, ..base.mechanics.clone() },
            psi_f_factor: Profile(vec![(5.0, 1.0), (7.0, 0.9)]),
            r_s_factor: Profile(vec![(9.0, 1.0), (11.0, 1.2)]),
            duration: 16.0,
            ..base
        },
        // Thesis Exp 2: position steps of 3 rad back and forth every 0.6 s through a 30 rad/s
        // trajectory filter (speed and acceleration fed forward), with the controller's K_t
        // 20 % high: its torque feed-forward falls short by 1/6. Set `control.adaptation`
        // to let the MRAS correct K_t in the loop.
        "exp2" => DriveConfig {
            control: super::config::Control {
                mode: Mode::Position,
                reference: Profile(
                    (0..5)
                        .flat_map(|j| {
                            let (t, to) = (0.2 + 0.6 * f64::from(j), if j % 2 == 0 { 3.0 } else { 0.0 });
                            [(t, 3.0 - to), (t, to)]
                        })
                        .collect(),
                ),
                position_filter: 30.0,
                k_t_factor: 1.2,
                ..c
            },
            duration: 3.2,
            ..base
        },
        // Thesis Exp 3: back-and-forth moves at increasing speeds, with a gravity-like arm.
        "exp3" => DriveConfig {
            control: super::config::Control {
                reference: Profile::back_and_forth(0.1, &[30.0, 100.0, 190.0, 280.0], 0.2, 0.3, 0.15),
                i_d: Profile(vec![(0.9, 0.0), (0.9, -0.3 * c.i_max), (1.7, -0.3 * c.i_max), (1.7, 0.0)]),
                ..c
            },
            mechanics: super::config::Mechanics { gravity: 0.2 * t_max, ..base.mechanics.clone() },
            duration: 7.2,
            ..base
        },
        // Thesis Exp 4: the moves of exp3 on a warm motor (winding 90 °C, magnets 70 °C).
        "exp4" => {
            let mut cfg = scenario("exp3", motor)?;
            cfg.name = name.into();
            cfg.thermal.winding = Profile::constant(90.0);
            cfg.thermal.magnet = Profile::constant(70.0);
            cfg
        }
        // Thesis Exp 5: low acceleration: slow ramps (1.5 s) to moderate speeds.
        "exp5" => DriveConfig {
            control: super::config::Control {
                reference: Profile::back_and_forth(0.1, &[50.0, 120.0], 1.5, 0.5, 0.3),
                i_d: Profile(vec![(0.5, 0.0), (0.5, -0.3 * c.i_max), (1.3, -0.3 * c.i_max), (1.3, 0.0)]),
                ..c
            },
            duration: 10.0,
            ..base
        },
        // Thesis Exp 6: material handling: pick-and-place moves of 20 rad with dwells, a load
        // carried on the way out, and a 0.5 s d-current injection every 4 s.
        "exp6" => {
            let mut position = vec![(0.0, 0.0)];
            let mut load = vec![(0.0, 0.0)];
            let mut i_d = vec![(0.0, 0.0)];
            let mut t = 0.2;
            for _ in 0..5 {
                position.extend([(t, 0.0), (t + 0.4, 20.0), (t + 0.8, 20.0), (t + 1.2, 0.0)]);
                load.extend([(t, 0.0), (t, 0.3 * t_max), (t + 0.8, 0.3 * t_max), (t + 0.8, 0.0)]);
                t += 1.6;
            }
            let mut s = 1.0;
            while s < t {
                i_d.extend([(s, 0.0), (s, -0.3 * c.i_max), (s + 0.5, -0.3 * c.i_max), (s + 0.5, 0.0)]);
                s += 4.0;
            }
            DriveConfig {
                control: super::config::Control {
                    mode: Mode::Position,
                    reference: Profile(position),
                    i_d: Profile(i_d),
                    ..c
                },
                mechanics: super::config::Mechanics { load: Profile(load), ..base.mechanics.clone() },
                duration: t,
                ..base
            }
        }
        // Standstill commissioning (issue 33): the rotor locked at θ_e = 15° (no phase current
        // near zero while either axis carries current, so the dead-time error's sign is
        // certain); the current loop steps i_d through ±20 % and ±50 % of i_max (0.1 s each),
        // then i_q (a torque reference) through ±30 % and ±15 %; a 2 V dead-time error,
        // current noise 1 % of i_max, and the winding temperature logged (constant at T_0
        // unless `thermal.winding` says otherwise).
        "standstill" => {
            let steps = |levels: &[f64], t0: f64| {
                let mut p = vec![(0.0, 0.0), (t0, 0.0)];
                for (j, l) in levels.iter().enumerate() {
                    let t = t0 + 0.1 * j as f64;
                    p.extend([(t, p.last().map_or(0.0, |x| x.1)), (t, *l)]);
                }
                let end = t0 + 0.1 * levels.len() as f64;
                p.extend([(end, p.last().map_or(0.0, |x| x.1)), (end, 0.0)]);
                Profile(p)
            };
            let i = c.i_max;
            DriveConfig {
                control: super::config::Control {
                    mode: Mode::Torque,
                    reference: steps(&[0.3 * t_max, -0.3 * t_max, 0.15 * t_max, -0.15 * t_max], 0.55),
                    i_d: steps(&[0.2 * i, 0.5 * i, -0.5 * i, -0.2 * i], 0.05),
                    ..c
                },
                mechanics: super::config::Mechanics {
                    locked: true,
                    theta0: std::f64::consts::PI / 12.0 / f64::from(motor.n_p),
                    ..base.mechanics.clone()
                },
                inverter: super::config::Inverter { v_dt: 2.0, ..base.inverter.clone() },
                sensors: super::config::Sensors {
                    current_noise: 0.01 * i,
                    winding_temperature: true,
                    ..base.sensors.clone()
                },
                duration: 1.0,
                ..base
            }
        }
        _ => {
            return Err(Error::InvalidOption {
                option: "scenario".into(),
                reason: format!(
                    "`{name}` is not one of {}, {}",
                    SCENARIOS.join(", "),
                    COMMISSIONING.join(", ")
                ),
            });
        }
    })
}
