//! The cascade controller of the simulated drive (MODEL.md §8, thesis ch. 4): position P →
//! speed PI → current PI in dq with decoupling feed-forward, lambda (IMC) tuning, current
//! and voltage limits with conditional-integration anti-windup.
//!
//! Sources: Harnefors, Nee, *Model-based current control of AC machines using the internal
//! model control method*, IEEE TIA 34(1), 1998 (`K_p = α_c L`, `K_i = α_c R`); the speed
//! PI `K_p = α_s J` of the same school (Harnefors, *Control of variable-speed drives*,
//! 2002, ch. 3).

use super::config::{Control, Mode};
use crate::error::Result;
use crate::online::{Mras, MrasConfig, Sample};
use crate::pmsm::MotorParameters;

/// What the controller measures at `t_k`.
#[derive(Clone, Copy, Debug)]
pub struct Measurement {
    /// d, q currents \[A\] (in the measured frame).
    pub i: [f64; 2],
    /// Mechanical speed \[rad/s\].
    pub w_m: f64,
    /// Mechanical angle \[rad\].
    pub theta_m: f64,
}

/// The controller's output at `t_k`.
#[derive(Clone, Copy, Debug)]
pub struct Command {
    /// dq voltage reference \[V\] (after the voltage limit).
    pub u: [f64; 2],
    /// dq current reference \[A\] (after the current limit).
    pub i_ref: [f64; 2],
    /// Speed reference of the speed loop \[rad/s\] (`None` in torque mode).
    pub w_ref: Option<f64>,
}

/// The controller's state: integrators and the machine model it believes in.
#[derive(Clone, Debug)]
pub struct Controller {
    cfg: Control,
    /// The controller's model of the machine (ψ_f scaled by `k_t_factor`).
    model: MotorParameters,
    inertia: f64,
    /// Current-loop integrators \[V\].
    int_i: [f64; 2],
    /// Speed-loop integrator \[N m\].
    int_w: f64,
    /// Trajectory filter state: position \[rad\] and speed \[rad/s\].
    filter: [f64; 2],
    /// The MRAS whose `K̂_t` the controller uses, if adaptive.
    mras: Option<Mras>,
}

impl Controller {
    /// A controller for `motor` (the plant at T_0; the controller's `ψ_f` is off by
    /// `cfg.k_t_factor`) on a load of inertia `inertia` \[kg m²\].
    ///
    /// # Errors
    /// Those of [`Mras::try_new`] with `cfg.adaptation`.
    pub fn new(cfg: &Control, motor: &MotorParameters, inertia: f64) -> Result<Self> {
        let model = MotorParameters { psi_f: motor.psi_f * cfg.k_t_factor, ..*motor };
        let mras = match &cfg.adaptation {
            None => None,
            Some(m) => Some(Mras::try_new(MrasConfig {
                n_p: model.n_p,
                l_s: model.l_d,
                h: cfg.h,
                k_e0: model.k_e(),
                r_s0: model.r_s,
                ..m.clone()
            })?),
        };
        Ok(Self { cfg: cfg.clone(), model, inertia, int_i: [0.0; 2], int_w: 0.0, filter: [0.0; 2], mras })
    }

    /// With adaptation, feeds the MRAS the sample (currents at `t_k` and the period-mean
    /// voltage the controller knows it applies over `[t_k, t_{k+1})`) and takes its `K̂_t`
    /// (a non-positive or non-finite estimate is ignored).
    ///
    /// # Errors
    /// Those of [`Mras::update`] (a non-finite sample).
    pub fn adapt(&mut self, s: &Sample) -> Result<()> {
        if let Some(m) = self.mras.as_mut() {
            let est = m.update(s)?;
            if est.psi_f.is_finite() && est.psi_f > 0.0 {
                self.model.psi_f = est.psi_f;
            }
        }
        Ok(())
    }

    /// The controller's `K_t` \[N m/A\] now.
    pub fn k_t(&self) -> f64 {
        self.model.k_t()
    }

    /// The voltage reference at time `t` \[s\] from the measurement `m`.
    pub fn update(&mut self, t: f64, m: &Measurement) -> Command {
        let c = &self.cfg;
        let h = c.h;
        // Outer loops: torque reference [N m].
        let mut w_ref_out = None;
        let torque = match c.mode {
            Mode::Torque => c.reference.at(t),
            Mode::Speed | Mode::Position => {
                let (w_ref, accel) = match c.mode {
                    Mode::Position if c.position_filter > 0.0 => {
                        // Critically damped trajectory filter (semi-implicit Euler).
                        let wn = c.position_filter;
                        let [th, w] = self.filter;
                        let a = wn * wn * (c.reference.at(t) - th) - 2.0 * wn * w;
                        let w = w + h * a;
                        self.filter = [th + h * w, w];
                        (c.k_position * (self.filter[0] - m.theta_m) + w, a)
                    }
                    Mode::Position => {
                        (c.k_position * (c.reference.at(t) - m.theta_m) + c.reference.slope(t), 0.0)
                    }
                    _ => (c.reference.at(t), c.reference.slope(t)),
                };
                w_ref_out = Some(w_ref);
                let k_p = c.alpha_s * self.inertia;
                let k_i = c.alpha_s * k_p / 5.0;
                let e = w_ref - m.w_m;
                let t_max = self.model.k_t() * c.i_max;
                let raw = k_p * e + self.int_w + self.inertia * accel;
                if raw.abs() < t_max || raw.signum() != e.signum() {
                    self.int_w += k_i * h * e;
                }
                raw.clamp(-t_max, t_max)
            }
        };
        // Current references with the limit |i| ≤ i_max (d first).
        let np = f64::from(self.model.n_p);
        let flux = |i_d: f64| 1.5 * np * (self.model.psi_f + (self.model.l_d - self.model.l_q) * i_d);
        let i_q_try = torque / flux(c.i_d.at(t));
        let i_d = (c.i_d.at(t) + c.i_d_ratio * i_q_try).clamp(-c.i_max, c.i_max);
        let i_q_max = (c.i_max * c.i_max - i_d * i_d).max(0.0).sqrt();
        let i_q = (torque / flux(i_d)).clamp(-i_q_max, i_q_max);
        // Current PI with decoupling feed-forward and the voltage limit U_dc/√3.
        let w_e = np * m.w_m;
        let p = &self.model;
        let e = [i_d - m.i[0], i_q - m.i[1]];
        let ff = [-w_e * p.l_q * m.i[1], w_e * (p.l_d * m.i[0] + p.psi_f)];
        let k_p = [c.alpha_c * p.l_d, c.alpha_c * p.l_q];
        let raw = [0, 1].map(|x| k_p[x] * e[x] + self.int_i[x] + ff[x]);
        let u_max = c.u_dc / 3f64.sqrt();
        let norm = raw[0].hypot(raw[1]);
        let scale = if norm > u_max { u_max / norm } else { 1.0 };
        if scale == 1.0 {
            for (int, e) in self.int_i.iter_mut().zip(e) {
                *int += c.alpha_c * p.r_s * h * e;
            }
        }
        Command { u: raw.map(|v| v * scale), i_ref: [i_d, i_q], w_ref: w_ref_out }
    }
}
