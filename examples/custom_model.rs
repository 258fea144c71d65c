//! A user-defined grey-box model fitted through the same API as the built-in ones.
//!
//! The model is a surface-magnet PMSM written in terms of the magnet flux ψ_f instead of
//! K_e, with the exact stator-hold step of MODEL.md §4 and *no* analytic sensitivities:
//! the estimator falls back to central finite differences of the step (crate
//! `finitediff`). The result is cross-checked against the built-in `PmsmSpm`.
//!
//! Run: `cargo run --release --example custom_model`

use greybox::estimate::{PemOptions, fit};
use greybox::model::{GreyBoxModel, Parameter, Signal};
use greybox::pmsm::C64;
use greybox::pmsm::{
    DqView, PmsmSpm, VoltageHold, channel, interval_mean_speed, read_log, rotation, stator_hold_start,
};
use greybox::{Experiment, Result};

/// θ = (r_s [Ω], l_s [H], psi_f [V s]); state and output (i_d, i_q) [A].
struct FluxSpm {
    /// Pole pairs n_p.
    n_p: u32,
    params: Vec<Parameter>,
}

/// Per interval: ω_e [rad/s], e^{−jω_e h}, and the stator-held voltage rotated to the period's end.
struct Inputs {
    h: f64,
    w_e: Vec<f64>,
    rot: Vec<C64>,
    u_end: Vec<C64>,
}

impl GreyBoxModel for FluxSpm {
    type Inputs = Inputs;
    type Coefficients = [f64; 3];

    fn name(&self) -> &str {
        "flux_spm"
    }
    fn n_states(&self) -> usize {
        2
    }
    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new(channel::I_D, "A"), Signal::new(channel::I_Q, "A")]
    }
    fn input_channels(&self) -> Vec<String> {
        vec![channel::U_D.into(), channel::U_Q.into(), channel::W_M.into()]
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }

    fn prepare(&self, e: &Experiment) -> Result<Inputs> {
        let v = DqView::try_new(e)?;
        let h = v.h();
        let (u_d, u_q) = v.terminal_voltage()?;
        let mut inputs = Inputs { h, w_e: vec![], rot: vec![], u_end: vec![] };
        for (k, w_m) in interval_mean_speed(v.w_m()).into_iter().enumerate() {
            let w_e = f64::from(self.n_p) * w_m;
            let phi = w_e * h;
            let rot = rotation(phi);
            // Start-of-period voltage u₀ = ū jφ/(1 − e^{−jφ}) (→ ū as φ → 0).
            let u0 = stator_hold_start(C64::new(u_d[k], u_q[k]), phi);
            inputs.w_e.push(w_e);
            inputs.rot.push(rot);
            inputs.u_end.push(u0 * rot);
        }
        Ok(inputs)
    }

    fn coefficients(&self, theta: &[f64], _: &Inputs) -> Result<[f64; 3]> {
        for (p, &v) in self.params.iter().zip(theta).take(2) {
            if !(v > 0.0 && v.is_finite()) {
                return Err(greybox::Error::InvalidParameter {
                    name: p.name.clone(),
                    value: v,
                    reason: "must be positive".into(),
                });
            }
        }
        Ok([theta[0], theta[1], theta[2]])
    }

    fn step(&self, c: &[f64; 3], inp: &Inputs, k: usize, x: &[f64], x_next: &mut [f64]) {
        let [r, l, psi] = *c;
        let w = inp.w_e[k];
        let z = C64::new(r, w * l);
        let a = (-z * inp.h / l).exp();
        let decay = (-r * inp.h / l).exp();
        let i = C64::new(x[0], x[1]);
        let n = a * i + inp.u_end[k] * ((1.0 - decay) / r) - (1.0 - a) / z * C64::new(0.0, w * psi);
        x_next[0] = n.re;
        x_next[1] = n.im;
    }
}

fn main() -> Result<()> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz");
    let log = read_log(path, &Default::default())?;
    let positive = |name: &str, unit: &str| Parameter { lower: 1e-12, ..Parameter::free(name, unit, 1.0) };
    let model = FluxSpm {
        n_p: 4,
        params: vec![positive("r_s", "ohm"), positive("l_s", "H"), positive("psi_f", "V s")],
    };

    // A rough start, as a user would have from a data sheet.
    let start = [1.2, 3.5e-3, 0.09];
    let custom = fit(&model, std::slice::from_ref(&log), &start, &PemOptions::default())?;
    println!("user-defined model (finite-difference sensitivities):\n{custom}");

    let builtin_start = [start[0], start[1], start[2] * 4.0 * (1.5f64).sqrt()];
    let builtin =
        fit(&PmsmSpm::new(model.n_p, VoltageHold::Stator), &[log], &builtin_start, &PemOptions::default())?;
    let psi_builtin =
        builtin.parameter("k_e").map(|p| p.value * (2.0f64 / 3.0).sqrt() / 4.0).unwrap_or(f64::NAN);
    for (name, a, b) in [
        ("r_s", custom.parameter("r_s").unwrap().value, builtin.parameter("r_s").unwrap().value),
        ("l_s", custom.parameter("l_s").unwrap().value, builtin.parameter("l_s").unwrap().value),
        ("psi_f", custom.parameter("psi_f").unwrap().value, psi_builtin),
    ] {
        println!(
            "{name}: user-defined {a:.9e}, built-in {b:.9e}, relative difference {:.1e}",
            ((a - b) / b).abs()
        );
    }
    Ok(())
}
