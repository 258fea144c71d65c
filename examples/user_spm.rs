//! A surface-magnet PMSM written by a user in a few lines, checked against the built-in
//! `PmsmSpm`: `cargo run --release --example user_spm`.
//!
//! The model below is the exact zero-order-hold step of a surface-magnet machine with a
//! voltage held in the stator frame (MODEL.md §4), built only from the public PMSM helpers
//! (`DqView`, `intervals`) and
//! without analytic sensitivities (the estimator takes finite differences of the step).
//! On the shipped log `data/sample.csv.gz` (servo motor, 4 pole pairs, stator hold) the
//! example
//!
//! 1. simulates both models at two parameter vectors and prints the largest difference of
//!    the simulated currents relative to the largest current (asserted ≤ 1e-10);
//! 2. fits both with `estimate::fit` from the same least-squares start and prints the two
//!    estimates side by side.
//!
//! The model code (between the `model code` comments) is 30 lines of rustfmt-formatted
//! code plus a one-line doc comment; the data-side work (interval-mean speed, rotation,
//! stator-hold voltage) comes from the public [`greybox::pmsm::intervals`].

use greybox::estimate::{PemOptions, fit};
use greybox::model::{GreyBoxModel, Parameter, Prepared, Signal};
use greybox::pmsm::{
    C64, DqView, Interval, MotorKind, PmsmSpm, VoltageHold, intervals, least_squares, read_log,
};
use greybox::simulate::{SimOptions, simulate};
use greybox::{Experiment, Result};

// --- model code (30 lines of code and one doc comment) ---
/// θ = (r_s [Ω], l_s [H], k_e [V s/rad]); state = output = (i_d, i_q) [A]; pole pairs n_p.
struct UserSpm(u32, Vec<Parameter>);
impl GreyBoxModel for UserSpm {
    type Inputs = (f64, Vec<Interval>); // h [s] and the data of every sample interval
    type Coefficients = [f64; 3];
    fn n_states(&self) -> usize {
        2
    }
    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new("id", "A"), Signal::new("iq", "A")]
    }
    fn input_channels(&self) -> Vec<String> {
        vec!["ud".into(), "uq".into(), "w_m".into()]
    }
    fn parameters(&self) -> &[Parameter] {
        &self.1
    }
    fn prepare(&self, e: &Experiment) -> Result<Self::Inputs> {
        Ok((e.h(), intervals(&DqView::try_new(e)?, self.0, VoltageHold::Stator)?.collect()))
    }
    fn coefficients(&self, th: &[f64], _: &Self::Inputs) -> Result<[f64; 3]> {
        Ok([th[0], th[1], th[2]])
    }
    fn step(&self, &[r, l, k_e]: &[f64; 3], (h, iv): &Self::Inputs, k: usize, x: &[f64], xn: &mut [f64]) {
        let (Interval { w_e, emf, rot, u0, .. }, d) = (iv[k], (-r * h / l).exp());
        let (a, z) = (rot * d, C64::new(r, w_e * l)); // MODEL.md §4, stator hold
        let i =
            a * C64::new(x[0], x[1]) + u0 * rot * ((1.0 - d) / r) - (1.0 - a) / z * C64::new(0.0, k_e * emf);
        (xn[0], xn[1]) = (i.re, i.im);
    }
}
// --- end of model code ---

fn main() -> Result<()> {
    const N_P: u32 = 4;
    let log = read_log(concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"), &Default::default())?;
    let builtin = PmsmSpm::new(N_P, VoltageHold::Stator);
    let user = UserSpm(N_P, builtin.parameters().to_vec());
    let start = least_squares(std::slice::from_ref(&log), N_P, MotorKind::Spm)?.theta;

    // 1. Simulated outputs of both models from the measured first current.
    let (prep_b, prep_u) = (Prepared::new(&builtin, &log)?, Prepared::new(&user, &log)?);
    let mut worst: f64 = 0.0;
    for theta in [start.clone(), vec![1.2, 3.5e-3, 0.5]] {
        let yb = simulate(&builtin, &prep_b, &theta, &SimOptions::default())?;
        let yu = simulate(&user, &prep_u, &theta, &SimOptions::default())?;
        let peak = yb.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = yb.iter().zip(&yu).fold(0.0f64, |m, (b, u)| m.max((b - u).abs()));
        let theta_text = theta.iter().map(|v| format!("{v:.4e}")).collect::<Vec<_>>().join(", ");
        println!(
            "θ = ({theta_text}): {} samples, max |ŷ_user − ŷ_PmsmSpm| = {diff:.3e} A, \
             max |ŷ| = {peak:.3} A, relative {:.3e}",
            log.len(),
            diff / peak
        );
        worst = worst.max(diff / peak);
    }
    println!("max relative difference of the simulated outputs: {worst:.3e}");
    assert!(worst <= 1e-10, "user model differs from PmsmSpm by {worst:e}");

    // 2. Both fits from the same least-squares start (user: finite differences).
    let options = PemOptions::default();
    let t = std::time::Instant::now();
    let fit_b = fit(&builtin, std::slice::from_ref(&log), &start, &options)?;
    let t_b = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let fit_u = fit(&user, std::slice::from_ref(&log), &start, &options)?;
    let t_u = t.elapsed().as_secs_f64();
    println!("\nuser-defined model (finite-difference sensitivities):\n{fit_u}");
    println!("{:<5} {:>18} {:>18} {:>12} {:>12}", "param", "PmsmSpm", "user_spm", "rel. diff", "diff / s.e.");
    for (b, u) in fit_b.parameters.iter().zip(&fit_u.parameters) {
        println!(
            "{:<5} {:>18.10e} {:>18.10e} {:>12.2e} {:>12.2e}",
            b.name,
            b.value,
            u.value,
            ((u.value - b.value) / b.value).abs(),
            (u.value - b.value).abs() / b.std_error
        );
    }
    println!(
        "iterations: PmsmSpm {} ({t_b:.2} s, analytic sensitivities), \
         user_spm {} ({t_u:.2} s, finite differences)",
        fit_b.solver.iterations, fit_u.solver.iterations
    );
    Ok(())
}

/// The example is also a test (`tests/it/examples.rs`): its assertions must hold.
#[cfg(test)]
#[test]
fn example_runs() {
    main().expect("the example runs");
}
