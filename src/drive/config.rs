//! What a simulated drive is made of: the motor, its mechanics and load, the controller and
//! its references, the inverter, the sensors, temperatures and parameter ramps (MODEL.md
//! §3, §4, §8; thesis ch. 4). Every part is plain data with serde, so a scenario is a JSON
//! file.

use super::profile::Profile;
use crate::error::{Error, Result};
use crate::pmsm::{MotorParameters, Saturation};
use serde::{Deserialize, Serialize};

/// Mechanics and load: `J dω_m/dt = T_e − B ω_m − T_c tanh(ω_m/ω_c) − m g l sin θ_m − T_L(t)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Mechanics {
    /// Inertia J \[kg m²\].
    pub inertia: f64,
    /// Viscous friction B \[N m s/rad\].
    pub viscous: f64,
    /// Coulomb friction T_c \[N m\], smoothed over `coulomb_speed`.
    pub coulomb: f64,
    /// Speed ω_c \[rad/s\] over which the Coulomb friction changes sign (tanh).
    pub coulomb_speed: f64,
    /// Gravity-like torque amplitude m g l \[N m\] (an arm: `m g l sin θ_m`).
    pub gravity: f64,
    /// External load torque T_L(t) \[N m\].
    pub load: Profile,
    /// RK4 sub-steps of the mechanics per sample period.
    pub substeps: usize,
    /// A locked rotor (a standstill test on a brake or a blocked shaft): the speed stays 0
    /// and the angle where it starts, whatever the torque.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub locked: bool,
    /// Rotor angle θ_m at t = 0 \[rad, mechanical\].
    #[serde(default, skip_serializing_if = "is_zero")]
    pub theta0: f64,
}

/// Whether `x` is 0 (a field left out of the scenario file then).
fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl Default for Mechanics {
    fn default() -> Self {
        Self {
            inertia: 2e-3,
            viscous: 1e-4,
            coulomb: 0.02,
            coulomb_speed: 1.0,
            gravity: 0.0,
            load: Profile::default(),
            substeps: 4,
            locked: false,
            theta0: 0.0,
        }
    }
}

/// What the outer loop follows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Torque reference \[N m\] straight to the current loop.
    Torque,
    /// Speed reference \[rad/s, mechanical\] through the speed PI.
    #[default]
    Speed,
    /// Position reference \[rad, mechanical\] through the position P and the speed PI.
    Position,
}

/// The cascade controller (MODEL.md §8, thesis ch. 4): current PI in dq with decoupling
/// feed-forward and lambda tuning (`K_p = α_c L`, `K_i = α_c R`), speed PI (`K_p = α_s J`,
/// `K_i = α_s K_p / 5`) with inertia feed-forward, position P with speed feed-forward.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Control {
    /// Sample (and control) period h \[s\].
    pub h: f64,
    /// Current-loop bandwidth α_c \[rad/s\].
    pub alpha_c: f64,
    /// Speed-loop bandwidth α_s \[rad/s\].
    pub alpha_s: f64,
    /// Position-loop gain \[1/s\].
    pub k_position: f64,
    /// Current limit |i| ≤ i_max \[A, peak\].
    pub i_max: f64,
    /// DC-link voltage U_dc \[V\]: the voltage limit is `U_dc/√3`.
    pub u_dc: f64,
    /// The controller's `K_t` (and `ψ_f`) relative to the plant's at T_0: 1.2 = 20 % too high.
    pub k_t_factor: f64,
    /// What the outer loop follows.
    pub mode: Mode,
    /// The reference of `mode` \[N m, rad/s or rad\].
    pub reference: Profile,
    /// d-current reference \[A\] (injection pulses; 0 for `i_d = 0` control).
    pub i_d: Profile,
    /// d-current reference as a fraction of the q-current reference, added to `i_d`.
    pub i_d_ratio: f64,
    /// Bandwidth ω_n \[rad/s\] of the critically damped trajectory filter a position
    /// reference passes through (its speed and acceleration feed forward); 0: none.
    pub position_filter: f64,
    /// Online `K_t` adaptation: the MRAS (thesis 5.1, [`crate::online`]) runs in the loop
    /// and the controller uses its `K̂_t`; `n_p`, `l_s`, `h` and the initial estimates are
    /// the controller's own. Surface magnets only. `None`: fixed `K_t`.
    pub adaptation: Option<crate::online::MrasConfig>,
}

impl Default for Control {
    fn default() -> Self {
        Self {
            h: 1e-4,
            alpha_c: std::f64::consts::TAU * 200.0,
            alpha_s: std::f64::consts::TAU * 8.0,
            k_position: 20.0,
            i_max: 10.0,
            u_dc: 320.0,
            k_t_factor: 1.0,
            mode: Mode::Speed,
            reference: Profile::default(),
            i_d: Profile::default(),
            i_d_ratio: 0.0,
            position_filter: 0.0,
            adaptation: None,
        }
    }
}

/// The averaged inverter: the reference computed at `t_k` acts over `[t_{k+d}, t_{k+d+1})`,
/// advanced by `advance ω_e h`, held in the stator frame, with the per-phase dead-time and
/// device-drop error `−v_dt tanh(i_x / width)` (MODEL.md §4).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Inverter {
    /// Computational delay d \[samples\].
    pub delay: usize,
    /// Modulator angle advance \[ω_e h\].
    pub advance: f64,
    /// Dead-time and device-drop voltage V_dt ≈ t_d f_sw U_dc + V_on \[V\]; 0 = ideal.
    pub v_dt: f64,
    /// Width of the smooth sign \[A\].
    pub width: f64,
    /// A switching-resolved PWM inverter instead of the averaged one (`v_dt` then unused):
    /// the fit's own model of [`crate::pmsm::PmsmPwm`], at the DC link `control.u_dc`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pwm: Option<PwmPlant>,
}

/// The switching-resolved inverter of the simulator: min-max modulation, double update
/// (the carrier at `1/(2h)`), dead time, device threshold and leg-state width.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct PwmPlant {
    /// Dead time t_d \[s\].
    pub t_d: f64,
    /// Device threshold voltage u_th \[V\].
    pub u_th: f64,
    /// Width i_w \[A\] of the smooth leg state `(2/π) atan(i/i_w)`; 0: the sign.
    pub i_w: f64,
    /// Levels of the PWM counter; 0: continuous duty ratios.
    pub levels: u32,
}

impl Default for Inverter {
    fn default() -> Self {
        Self { delay: 1, advance: 1.5, v_dt: 0.0, width: 0.05, pwm: None }
    }
}

/// Sensor imperfections (all off by default): Gaussian noise, ADC and encoder quantisation.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Sensors {
    /// Phase-current noise σ \[A\] (the stationary standard deviation).
    pub current_noise: f64,
    /// Pole a of the phase-current noise, an AR(1) process `n_k = a n_{k−1} + √(1 − a²) σ e_k`
    /// with white unit e (in \[0, 1); 0: white noise).
    pub current_noise_pole: f64,
    /// Speed noise σ \[rad/s\].
    pub speed_noise: f64,
    /// Noise σ on the logged terminal voltage \[V\] (not seen by the motor).
    pub voltage_noise: f64,
    /// Current ADC resolution \[bits\] over ±`adc_range`; `None`: not quantised.
    pub adc_bits: Option<u32>,
    /// Current ADC full scale \[A\].
    pub adc_range: f64,
    /// Encoder counts per mechanical revolution; `None`: exact angle.
    pub encoder_counts: Option<u32>,
    /// Log the winding temperature \[°C\] of `thermal.winding` (channel `t_winding`, as a
    /// winding sensor would; exact).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub winding_temperature: bool,
}

/// Temperatures \[°C\] acting on `R_s(T) = R_s0 (1 + α (T − T_0))` and
/// `ψ_f(T) = ψ_f0 (1 + β (T − T_0))` (MODEL.md §3, thesis 3.4); empty profiles stay at T_0.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Thermal {
    /// Reference temperature T_0 \[°C\] of the motor parameters.
    pub t0: f64,
    /// Winding temperature \[°C\].
    pub winding: Profile,
    /// Magnet temperature \[°C\].
    pub magnet: Profile,
}

impl Default for Thermal {
    fn default() -> Self {
        Self { t0: 20.0, winding: Profile::default(), magnet: Profile::default() }
    }
}

impl Thermal {
    /// The temperature \[°C\] of `profile` (`winding` or `magnet`) at time `t` \[s\]: `t0`
    /// for an empty profile.
    pub fn at(&self, profile: &Profile, t: f64) -> f64 {
        if profile.0.is_empty() { self.t0 } else { profile.at(t) }
    }
}

/// A whole drive: the plant, its controller and everything between them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DriveConfig {
    /// Scenario name (goes to the truth file).
    pub name: String,
    /// The motor's parameters at T_0.
    pub motor: MotorParameters,
    /// Mechanics and load.
    pub mechanics: Mechanics,
    /// Controller and references.
    pub control: Control,
    /// Inverter.
    pub inverter: Inverter,
    /// Sensors.
    pub sensors: Sensors,
    /// Temperatures.
    pub thermal: Thermal,
    /// Plant `R_s` relative to its thermal value over time (empty: 1).
    pub r_s_factor: Profile,
    /// Plant `ψ_f` (hence `K_e`, `K_t`) relative to its thermal value over time (empty: 1).
    pub psi_f_factor: Profile,
    /// Length of the record \[s\].
    pub duration: f64,
    /// Seed of the noise.
    pub seed: u64,
    /// Magnetic saturation of the plant (absent: linear magnetics, `motor.l_d`, `motor.l_q`,
    /// `motor.psi_f`). When present the plant's flux follows this model
    /// ([`crate::pmsm::saturated_step`]) with `R_s` from `motor` (and its temperature and
    /// ramp); `motor`'s inductances and `ψ_f` are then what the controller assumes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub saturation: Option<Saturation>,
}

impl Default for DriveConfig {
    fn default() -> Self {
        Self {
            name: "custom".into(),
            motor: super::motors::SPM_MOTOR,
            mechanics: Mechanics::default(),
            control: Control::default(),
            inverter: Inverter::default(),
            sensors: Sensors::default(),
            thermal: Thermal::default(),
            r_s_factor: Profile::default(),
            psi_f_factor: Profile::default(),
            duration: 2.0,
            seed: 1,
            saturation: None,
        }
    }
}

impl DriveConfig {
    /// Number of samples `⌊duration/h⌋ + 1`.
    pub fn samples(&self) -> usize {
        (self.duration / self.control.h).floor() as usize + 1
    }

    /// Checks every value before a simulation.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming the field (e.g. `mechanics.inertia`); those of
    /// [`MotorParameters::validate`] and [`Profile::validate`].
    pub fn validate(&self) -> Result<()> {
        self.motor.validate()?;
        let positive = [
            ("mechanics.inertia", self.mechanics.inertia),
            ("mechanics.coulomb_speed", self.mechanics.coulomb_speed),
            ("control.h", self.control.h),
            ("control.alpha_c", self.control.alpha_c),
            ("control.alpha_s", self.control.alpha_s),
            ("control.i_max", self.control.i_max),
            ("control.u_dc", self.control.u_dc),
            ("control.k_t_factor", self.control.k_t_factor),
            ("inverter.width", self.inverter.width),
            ("duration", self.duration),
        ];
        let non_negative = [
            ("mechanics.viscous", self.mechanics.viscous),
            ("mechanics.coulomb", self.mechanics.coulomb),
            ("control.k_position", self.control.k_position),
            ("control.position_filter", self.control.position_filter),
            ("inverter.v_dt", self.inverter.v_dt),
            ("inverter.pwm.t_d", self.inverter.pwm.map_or(0.0, |p| p.t_d)),
            ("inverter.pwm.u_th", self.inverter.pwm.map_or(0.0, |p| p.u_th)),
            ("inverter.pwm.i_w", self.inverter.pwm.map_or(0.0, |p| p.i_w)),
            ("sensors.current_noise", self.sensors.current_noise),
            ("sensors.speed_noise", self.sensors.speed_noise),
            ("sensors.voltage_noise", self.sensors.voltage_noise),
            ("sensors.adc_range", self.sensors.adc_range),
            ("sensors.current_noise_pole", self.sensors.current_noise_pole),
        ];
        let finite = [
            ("mechanics.gravity", self.mechanics.gravity),
            ("mechanics.theta0", self.mechanics.theta0),
            ("control.i_d_ratio", self.control.i_d_ratio),
            ("inverter.advance", self.inverter.advance),
            ("thermal.t0", self.thermal.t0),
        ];
        let bad = |name: &str, v: f64, what: &str| Error::InvalidOption {
            option: name.into(),
            reason: format!("{v} must be {what}"),
        };
        for (n, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(n, v, "positive and finite"));
            }
        }
        for (n, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(n, v, "non-negative and finite"));
            }
        }
        for (n, v) in finite {
            if !v.is_finite() {
                return Err(bad(n, v, "finite"));
            }
        }
        if self.sensors.current_noise_pole >= 1.0 {
            return Err(bad(
                "sensors.current_noise_pole",
                self.sensors.current_noise_pole,
                "below 1 (a stable AR(1) pole)",
            ));
        }
        if self.control.position_filter * self.control.h > 0.5 {
            return Err(bad("control.position_filter", self.control.position_filter, "at most 0.5/h"));
        }
        if let Some(sat) = &self.saturation {
            sat.check()
                .map_err(|e| Error::InvalidOption { option: "saturation".into(), reason: e.to_string() })?;
            let constant = |p: &Profile| p.0.iter().all(|&(_, v)| v == 1.0);
            if !constant(&self.psi_f_factor) || !self.thermal.magnet.0.is_empty() {
                return Err(Error::InvalidOption {
                    option: "saturation".into(),
                    reason:
                        "the saturated plant has no ψ_f ramp or magnet temperature: remove psi_f_factor and \
                             thermal.magnet"
                            .into(),
                });
            }
        }
        if self.control.adaptation.is_some() && self.motor.salient() {
            return Err(Error::InvalidOption {
                option: "control.adaptation".into(),
                reason: "the MRAS observer is for surface magnets (l_d = l_q)".into(),
            });
        }
        if self.mechanics.substeps == 0 || self.mechanics.substeps > 1000 {
            return Err(bad("mechanics.substeps", self.mechanics.substeps as f64, "in 1..=1000"));
        }
        if let Some(b) = self.sensors.adc_bits.filter(|b| !(2..=32).contains(b)) {
            return Err(bad("sensors.adc_bits", f64::from(b), "in 2..=32"));
        }
        if self.sensors.adc_bits.is_some() && self.sensors.adc_range <= 0.0 {
            return Err(bad("sensors.adc_range", self.sensors.adc_range, "positive with adc_bits"));
        }
        if self.sensors.encoder_counts == Some(0) {
            return Err(bad("sensors.encoder_counts", 0.0, "positive"));
        }
        // A record is held in memory: 11 channels of 8 bytes per sample.
        if self.samples() > 50_000_000 {
            return Err(bad("duration", self.duration, "at most 5·10⁷ samples long"));
        }
        for (n, p) in [
            ("mechanics.load", &self.mechanics.load),
            ("control.reference", &self.control.reference),
            ("control.i_d", &self.control.i_d),
            ("thermal.winding", &self.thermal.winding),
            ("thermal.magnet", &self.thermal.magnet),
            ("r_s_factor", &self.r_s_factor),
            ("psi_f_factor", &self.psi_f_factor),
        ] {
            p.validate(n)?;
        }
        Ok(())
    }
}
