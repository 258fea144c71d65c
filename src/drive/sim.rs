//! The closed-loop simulation: controller, delayed and advanced averaged inverter, exact
//! electrical step, RK4 mechanics, sensors; one period at a time.
//!
//! Per period `[t_k, t_{k+1})`:
//! 1. the sensors measure `i[k]`, `ω_m[k]`, `θ_m[k]` (noise, ADC and encoder quantisation);
//! 2. the controller computes `u_ref[k]` (logged as `ud_ref, uq_ref`);
//! 3. the inverter applies `u_ref[k − d]` advanced by `a ω̂_e[k − d] h` from the angle the
//!    controller measured then, held in the stator frame, plus the dead-time error
//!    `−V_dt tanh(i_x/w)` of the phase currents at `t_k` (MODEL.md §4);
//! 4. the mechanics advance with the torque of `i[k]` held over the period (RK4 sub-steps
//!    on ω_m; the angle by the trapezoid `θ_m[k+1] = θ_m[k] + h (ω_m[k] + ω_m[k+1])/2`,
//!    the rotation the electrical step assumes);
//! 5. the electrical state advances by the offline models' exact stator-hold step at the
//!    period's mean speed ([`ExactPlant`]), with the parameters of `t_k` (temperatures and
//!    ramps); the logged `ud, uq` is the applied voltage's exact period mean in dq.
//!
//! So a log of this simulator is reproduced to rounding by the matching offline model with
//! the true parameters, for either voltage column.

use super::config::DriveConfig;
use super::control::{Controller, Measurement};
use crate::data::{Channel, Experiment};
use crate::error::{Error, Result};
use crate::online::Sample;
use crate::pmsm::{
    ALPHA_COPPER, BETA_NDFEB, C64, DqSignals, ExactPlant, MotorParameters, VoltageHold, stator_hold_start,
};
use crate::pmsm::{clarke, inverse_clarke, inverse_park, park, saturated_step, saturated_substeps};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// The truth of a simulated log, written beside it as JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Scenario name.
    pub scenario: String,
    /// The plant at the start of the record.
    pub start: MotorParameters,
    /// The plant at the end of the record.
    pub end: MotorParameters,
    /// `K_e` at the start \[V s/rad\].
    pub k_e: f64,
    /// `K_t` at the start \[N m/A\].
    pub k_t: f64,
    /// Whether the plant's parameters change within the record.
    pub time_varying: bool,
    /// Sample time h \[s\].
    pub h: f64,
    /// Number of samples N.
    pub samples: usize,
    /// The configuration that produced the log.
    pub config: DriveConfig,
}

/// A simulated drive log: the experiment (channels `ud, uq, id, iq, w_m, theta_m, ud_ref,
/// uq_ref, id_ref, iq_ref`, as `greybox fit` reads them, plus `w_ref` [rad/s], the speed
/// loop's reference, in speed and position modes, and `k_t_ctrl` \[N m/A\], the controller's
/// `K_t`, with adaptation, and `t_winding` \[°C\] with `sensors.winding_temperature`) and
/// its truth.
#[derive(Clone, Debug)]
pub struct DriveLog {
    /// The log.
    pub experiment: Experiment,
    /// What produced it.
    pub truth: Truth,
}

/// The plant's parameters at time `t` \[s\]: thermal values, then the ramps.
pub fn plant_at(cfg: &DriveConfig, t: f64) -> MotorParameters {
    let th = &cfg.thermal;
    let temp = |p: &super::Profile| th.at(p, t);
    let factor = |p: &super::Profile| if p.0.is_empty() { 1.0 } else { p.at(t) };
    let m = &cfg.motor;
    MotorParameters {
        r_s: m.r_s * (1.0 + ALPHA_COPPER * (temp(&th.winding) - th.t0)) * factor(&cfg.r_s_factor),
        psi_f: m.psi_f * (1.0 + BETA_NDFEB * (temp(&th.magnet) - th.t0)) * factor(&cfg.psi_f_factor),
        ..*m
    }
}

/// Simulates the drive of `cfg` for `cfg.duration` seconds.
///
/// # Errors
/// Those of [`DriveConfig::validate`]; [`Error::SimulationDiverged`] naming the sample when
/// the state stops being finite (e.g. parameters turned non-physical by a ramp).
pub fn simulate_drive(cfg: &DriveConfig) -> Result<DriveLog> {
    simulate_drive_with_progress(cfg, &mut |_, _| {})
}

/// Samples between two calls of the progress callback of [`simulate_drive_with_progress`].
pub const PROGRESS_EVERY: usize = 1 << 14;

/// [`simulate_drive`], calling `progress(k, n)` every [`PROGRESS_EVERY`] samples and at
/// the end (`k` samples of `n` done), e.g. for a progress bar; the log is the same.
///
/// # Errors
/// Those of [`simulate_drive`].
pub fn simulate_drive_with_progress(
    cfg: &DriveConfig,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<DriveLog> {
    cfg.validate()?;
    let (h, n, np) = (cfg.control.h, cfg.samples(), f64::from(cfg.motor.n_p));
    let mut plant = ExactPlant::new(cfg.motor.n_p, h, cfg.motor.salient(), VoltageHold::Stator)?;
    let mut ctrl = Controller::new(&cfg.control, &cfg.motor, cfg.mechanics.inertia)?;
    // A saturated plant: RK4 substeps for four times the model's accuracy rule at the
    // speed where the back-EMF reaches twice the voltage limit.
    let saturated = match &cfg.saturation {
        Some(sat) => {
            let w_e_max = 2.0 * cfg.control.u_dc / 3f64.sqrt() / sat.psi_f.abs().max(1e-3);
            let r_s_max =
                (0..=100).map(|j| plant_at(cfg, cfg.duration * f64::from(j) / 100.0).r_s).fold(0.0, f64::max);
            Some((sat, 4 * saturated_substeps(sat, r_s_max, 2.0 * cfg.control.i_max, w_e_max, h)?))
        }
        None => None,
    };
    let (mut w_refs, mut k_ts, mut t_winding) = (Vec::new(), Vec::new(), Vec::new());
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let gauss = |rng: &mut ChaCha8Rng, s: f64| {
        if s > 0.0 { Normal::new(0.0, s).map_or(0.0, |d| d.sample(rng)) } else { 0.0 }
    };
    let s = &cfg.sensors;
    let adc = |x: f64| match s.adc_bits {
        Some(b) => {
            let q = 2.0 * s.adc_range / f64::from(b).exp2();
            (x / q).round().clamp(-s.adc_range / q, s.adc_range / q) * q
        }
        None => x,
    };
    let encoder = |th: f64| match s.encoder_counts {
        Some(c) => {
            let q = std::f64::consts::TAU / f64::from(c);
            (th / q).floor() * q
        }
        None => th,
    };
    let inv = &cfg.inverter;
    let mut pwm_plant = crate::pmsm::PwmPlantStep::default();
    let pwm_model = inv.pwm.map(|p| crate::pmsm::PwmInverter {
        levels: (p.levels > 0).then_some(p.levels),
        ..crate::pmsm::PwmInverter::default()
    });
    if inv.pwm.is_some() && saturated.is_some() {
        return Err(Error::InvalidOption {
            option: "inverter.pwm".into(),
            reason: "the switching-resolved inverter drives the linear motor models, not the saturated one"
                .into(),
        });
    }
    let mut log = [(); 10].map(|_| Vec::with_capacity(n));
    let (mut i, mut w, mut theta) = ([0.0; 2], 0.0, cfg.mechanics.theta0);
    // The phase-current noise of phases a and b (AR(1) with pole `current_noise_pole`).
    let mut noise = [0.0; 2];
    // The commands and the controller's angle and speed of the last d + 1 samples.
    let mut history: std::collections::VecDeque<(C64, f64, f64)> = std::collections::VecDeque::new();
    let diverged = |k: usize, p: &MotorParameters| Error::SimulationDiverged {
        experiment: cfg.name.clone(),
        sample: k,
        parameters: format!("{p:?}"),
    };
    for k in 0..n {
        if k % PROGRESS_EVERY == 0 {
            progress(k, n);
        }
        let t = k as f64 * h;
        let p = plant_at(cfg, t);
        // 1. Sensors: phase currents with noise and ADC, angle by the encoder.
        let th_e = np * theta;
        let (a, b) = inverse_park(i[0], i[1], th_e);
        let (ia, ib, ic) = inverse_clarke(a, b);
        let (a1, b1) = (gauss(&mut rng, s.current_noise), gauss(&mut rng, s.current_noise));
        let gain = (1.0 - s.current_noise_pole * s.current_noise_pole).sqrt();
        noise = [s.current_noise_pole * noise[0] + gain * a1, s.current_noise_pole * noise[1] + gain * b1];
        let (ia_m, ib_m) = (adc(ia + noise[0]), adc(ib + noise[1]));
        let theta_meas = encoder(theta);
        let (al, be) = clarke(ia_m, ib_m, -ia_m - ib_m);
        let (id_m, iq_m) = park(al, be, np * theta_meas);
        let w_meas = w + gauss(&mut rng, s.speed_noise);
        let m = Measurement { i: [id_m, iq_m], w_m: w_meas, theta_m: theta_meas };
        // 2. Controller.
        let cmd = ctrl.update(t, &m);
        history.push_back((C64::new(cmd.u[0], cmd.u[1]), np * theta_meas, np * w_meas));
        while history.len() > inv.delay + 1 {
            history.pop_front();
        }
        // 3. Inverter: the reference of k − d (the first one before that), in the stator frame.
        let applied = history.front().copied().filter(|_| history.len() == inv.delay + 1);
        let mut u_s =
            applied.map_or(C64::default(), |(u, th, we)| u * C64::from_polar(1.0, th + inv.advance * we * h));
        if cfg.control.adaptation.is_some() {
            // The voltage the controller knows it applies, in its own frame, as a period mean.
            let u0 = u_s * C64::from_polar(1.0, -np * theta_meas);
            let mean = u0 / stator_hold_start(C64::new(1.0, 0.0), np * w_meas * h);
            let sample = Sample { i_d: id_m, i_q: iq_m, u_d: mean.re, u_q: mean.im, w_m: w_meas };
            ctrl.adapt(&sample).map_err(|_| diverged(k, &p))?;
            k_ts.push(ctrl.k_t());
        }
        if s.winding_temperature {
            t_winding.push(cfg.thermal.at(&cfg.thermal.winding, t));
        }
        if let Some(w) = cmd.w_ref {
            w_refs.push(w);
        }
        if inv.v_dt > 0.0 && inv.pwm.is_none() {
            let sign = |x: f64| -(x / inv.width).tanh();
            // The true phase currents at t_k (not the measured ones).
            let (ea, eb) = clarke(sign(ia), sign(ib), sign(ic));
            u_s += C64::new(ea, eb) * inv.v_dt;
        }
        let u0 = u_s * C64::from_polar(1.0, -th_e);
        // 4. Mechanics.
        let t_e = match saturated {
            Some((sat, _)) => sat.torque(cfg.motor.n_p, sat.flux(i).map_err(|_| diverged(k, &p))?),
            None => p.torque(i[0], i[1]),
        };
        let w_next = mechanics(cfg, t, t_e, theta, w);
        let w_mean = 0.5 * (w + w_next);
        let phi = np * w_mean * h;
        let pwm_step = match (inv.pwm, &pwm_model) {
            (Some(pp), Some(model)) => Some(pwm_plant.step(
                model,
                [p.r_s, p.l_d, p.l_q, p.k_e()],
                [pp.t_d, pp.u_th, pp.i_w],
                i,
                th_e,
                np * w_mean,
                w_mean,
                [np * (w_next - w) / h, (w_next - w) / h],
                [u_s.re, u_s.im],
                cfg.control.u_dc,
                h,
            )),
            _ => None,
        };
        let mean = match pwm_step {
            Some((_, m)) => C64::new(m[0], m[1]),
            None => u0 / stator_hold_start(C64::new(1.0, 0.0), phi),
        };
        for (c, v) in log.iter_mut().zip([
            mean.re + gauss(&mut rng, s.voltage_noise),
            mean.im + gauss(&mut rng, s.voltage_noise),
            id_m,
            iq_m,
            w_meas,
            theta_meas,
            cmd.u[0],
            cmd.u[1],
            cmd.i_ref[0],
            cmd.i_ref[1],
        ]) {
            c.push(v);
        }
        // 5. Electrical step.
        i = match (pwm_step, saturated) {
            (Some((next, _)), _) if next.iter().all(|x| x.is_finite()) => Ok(next),
            (Some(_), _) => return Err(diverged(k, &p)),
            (None, Some((sat, m))) => saturated_step(sat, p.r_s, i, u0, np * w_mean, h, m),
            (None, None) => plant.step(&p, i, u0, w_mean),
        }
        .map_err(|_| diverged(k, &p))?;
        theta += h * w_mean;
        w = w_next;
        if !(w.is_finite() && theta.is_finite()) {
            return Err(diverged(k, &p));
        }
    }
    let [u_d, u_q, i_d, i_q, w_m, theta_m, u_d_ref, u_q_ref, id_ref, iq_ref] = log;
    let signals = DqSignals {
        u_d,
        u_q,
        i_d,
        i_q,
        w_m,
        theta_m: Some(theta_m),
        u_d_ref: Some(u_d_ref),
        u_q_ref: Some(u_q_ref),
    };
    let mut channels = signals.into_channels();
    channels.push(Channel::new("id_ref", "A", id_ref));
    channels.push(Channel::new("iq_ref", "A", iq_ref));
    if w_refs.len() == n {
        channels.push(Channel::new("w_ref", "rad/s", w_refs));
    }
    if k_ts.len() == n {
        channels.push(Channel::new("k_t_ctrl", "N m/A", k_ts));
    }
    if t_winding.len() == n {
        channels.push(Channel::new(crate::pmsm::WINDING_TEMPERATURE, "°C", t_winding));
    }
    let experiment = Experiment::try_new(cfg.name.clone(), h, channels)?;
    let (start, end) = (plant_at(cfg, 0.0), plant_at(cfg, (n - 1) as f64 * h));
    let time_varying = (0..=100).any(|j| plant_at(cfg, cfg.duration * f64::from(j) / 100.0) != start);
    let truth = Truth {
        scenario: cfg.name.clone(),
        start,
        end,
        k_e: start.k_e(),
        k_t: start.k_t(),
        time_varying,
        h,
        samples: n,
        config: cfg.clone(),
    };
    progress(n, n);
    Ok(DriveLog { experiment, truth })
}

/// ω_m at the end of the period from `w` at `t` \[s\], angle `theta` \[rad\], with the motor
/// torque `t_e` \[N m\] held: RK4 sub-steps of `J ω̇ = T_e − B ω − T_c tanh(ω/ω_c) − m g l
/// sin θ − T_L(t)`, `θ̇ = ω`; 0 for a locked rotor.
fn mechanics(cfg: &DriveConfig, t: f64, t_e: f64, theta: f64, w: f64) -> f64 {
    let m = &cfg.mechanics;
    if m.locked {
        return 0.0;
    }
    let f = |t: f64, th: f64, w: f64| {
        (t_e - m.viscous * w - m.coulomb * (w / m.coulomb_speed).tanh() - m.gravity * th.sin() - m.load.at(t))
            / m.inertia
    };
    let dt = cfg.control.h / m.substeps as f64;
    let (mut tt, mut th, mut ww) = (t, theta, w);
    for _ in 0..m.substeps {
        let (k1w, k1t) = (f(tt, th, ww), ww);
        let (k2w, k2t) = (f(tt + 0.5 * dt, th + 0.5 * dt * k1t, ww + 0.5 * dt * k1w), ww + 0.5 * dt * k1w);
        let (k3w, k3t) = (f(tt + 0.5 * dt, th + 0.5 * dt * k2t, ww + 0.5 * dt * k2w), ww + 0.5 * dt * k2w);
        let (k4w, k4t) = (f(tt + dt, th + dt * k3t, ww + dt * k3w), ww + dt * k3w);
        ww += dt / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w);
        th += dt / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t);
        tt += dt;
    }
    ww
}
