//! A static grey-box model (no state): Michaelis-Menten kinetics `y = V x/(K + x)` fitted
//! from a handful of samples: `cargo run --release --example static_regression`.
//!
//! Input channel `x`, substrate concentration [mol/m³]; output channel `y`, reaction rate
//! [mol/(m³ s)]; parameters `v_max` [mol/(m³ s)] and `k_m` [mol/m³]. The model is
//! nonlinear in `k_m`, so this is a real nonlinear regression, solved by the same
//! prediction-error fit as the dynamic models (finite-difference sensitivities).
//!
//! With `n_states() = 0` nothing is simulated and nothing is padded: there is no initial
//! state to take from the first sample, so every observation is a residual. The example
//! fits noise-free data with N = 5 samples and with the minimum N = n_θ + 1 = 3, asserts
//! that the fit counts all N samples and recovers the parameters to 1e-8 (relative), and
//! shows what happens with N = 2 = n_θ (no degrees of freedom left for the statistics).

use greybox::estimate::{FitResult, PemOptions, fit};
use greybox::model::{GreyBoxModel, Parameter, Signal};
use greybox::{Channel, Experiment, Result};

/// True maximum rate [mol/(m³ s)].
const V_MAX: f64 = 1.8;
/// True half-saturation concentration [mol/m³].
const K_M: f64 = 0.6;

/// `y = V x/(K + x)`, θ = (v_max, k_m).
struct MichaelisMenten {
    params: Vec<Parameter>,
}

impl GreyBoxModel for MichaelisMenten {
    /// The concentrations x, length N.
    type Inputs = Vec<f64>;
    /// (V, K).
    type Coefficients = (f64, f64);

    fn name(&self) -> &str {
        "michaelis_menten"
    }
    fn n_states(&self) -> usize {
        0
    }
    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new("y", "mol/(m^3 s)")]
    }
    fn input_channels(&self) -> Vec<String> {
        vec!["x".into()]
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn prepare(&self, e: &Experiment) -> Result<Vec<f64>> {
        Ok(e.channel("x")?.to_vec())
    }
    fn coefficients(&self, theta: &[f64], _: &Vec<f64>) -> Result<(f64, f64)> {
        Ok((theta[0], theta[1]))
    }
    fn step(&self, _: &(f64, f64), _: &Vec<f64>, _: usize, _: &[f64], _: &mut [f64]) {}
    fn output(&self, &(v, k): &(f64, f64), x: &Vec<f64>, i: usize, _: &[f64], y: &mut [f64]) {
        y[0] = v * x[i] / (k + x[i]);
    }
}

/// A noise-free experiment at concentrations `x`.
fn experiment(x: &[f64]) -> Result<Experiment> {
    let y = x.iter().map(|x| V_MAX * x / (K_M + x)).collect();
    // The "sample time" of a static experiment means nothing; any positive value will do.
    Experiment::try_new(
        format!("{} samples", x.len()),
        1.0,
        vec![Channel::new("x", "mol/m^3", x.to_vec()), Channel::new("y", "mol/(m^3 s)", y)],
    )
}

/// Fits from a start 40–70 % off and prints the estimates and their relative errors.
fn fit_samples(model: &MichaelisMenten, x: &[f64]) -> Result<(FitResult, f64)> {
    let e = experiment(x)?;
    let fit = fit(model, &[e], &[1.0, 1.0], &PemOptions::default())?;
    let mut worst: f64 = 0.0;
    println!(
        "N = {}: x = {x:?} mol/m³; fit counts {} samples, {} degrees of freedom; {} after {} iterations",
        x.len(),
        fit.fit.samples,
        fit.fit.dof,
        fit.solver.termination,
        fit.solver.iterations
    );
    for (name, truth) in [("v_max", V_MAX), ("k_m", K_M)] {
        let p = fit.parameter(name).expect("estimated");
        let rel = ((p.value - truth) / truth).abs();
        worst = worst.max(rel);
        println!(
            "  {name:<5} = {:.12} {} (truth {truth}), relative error {rel:.2e}, std error {:.2e}",
            p.value, p.unit, p.std_error
        );
    }
    Ok((fit, worst))
}

fn main() -> Result<()> {
    let model = MichaelisMenten {
        params: vec![
            Parameter::positive("v_max", "mol/(m^3 s)", 1.0),
            Parameter::positive("k_m", "mol/m^3", 1.0),
        ],
    };
    for x in [&[0.1, 0.3, 0.8, 2.0, 5.0][..], &[0.2, 1.0, 4.0]] {
        let (fit, worst) = fit_samples(&model, x)?;
        assert_eq!(fit.fit.samples, x.len(), "every observation of a static model counts");
        assert!(worst <= 1e-8, "noise-free recovery to 1e-8, got {worst:e}");
        assert!(fit.solver.success);
    }
    // With N = n_θ the two parameters still interpolate the two points, but nothing is
    // left to estimate the noise from: the statistics have no degrees of freedom.
    match fit_samples(&model, &[0.5, 3.0]) {
        Ok((fit, _)) => {
            for p in &fit.parameters {
                println!(
                    "  N = n_θ, {} degrees of freedom: {} std error {:.2e}, 95 % interval [{:e}, {:e}]",
                    fit.fit.dof, p.name, p.std_error, p.ci95[0], p.ci95[1]
                );
            }
        }
        Err(e) => println!("  N = n_θ refused: {e}"),
    }
    Ok(())
}

/// The example is also a test (`tests/it/examples.rs`): its assertions must hold.
#[cfg(test)]
#[test]
fn example_runs() {
    main().expect("the example runs");
}
