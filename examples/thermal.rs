//! A grey-box model that is not a motor: the first-order thermal model of a winding,
//! with analytic sensitivities: `cargo run --release --example thermal`.
//!
//! ```text
//! C_th dT/dt = P_cu − (T − T_amb)/R_th
//! ```
//!
//! Input channels copper losses `p_cu` [W] and ambient temperature `t_amb` [K], both held
//! over `[t_k, t_k + h)`; output (and state) the winding temperature `t_w` [K]; parameters
//! `r_th` [K/W] and `c_th` [J/K]. With inputs held over a period the step is exact:
//! `T[k+1] = a T[k] + (1 − a)(T_amb[k] + R_th P_cu[k])`, `a = exp(−h/(R_th C_th))`, and so
//! are its derivatives, implemented through the `Sensitivities` trait.
//!
//! The example makes its own log: four hours of a random load cycle at h = 1 s (a small
//! xorshift generator written below, no RNG crate), integrated by RK4 with 100 substeps per
//! sample, independently of the model's exact step. It then
//!
//! 1. checks the analytic sensitivities against a central difference of the whole
//!    simulated record and against the library's own finite differences (the same model
//!    with `sensitivities()` returning `None`), printing the largest relative differences.
//!    The library's are the less precise here: it differentiates each step with an
//!    absolute step of ∛ε ≈ 6e-6 in the state, small against temperatures of 300–400 K, so
//!    `∂T[k+1]/∂T[k]` carries a rounding error of about 1e-8 that the recursion accumulates;
//! 2. fits the noise-free log and asserts a relative error ≤ 1e-6 on both parameters;
//! 3. fits the log with Gaussian noise σ = 0.2 K on the measured temperature and asserts
//!    that each estimate lies within 3 reported standard errors of the truth (z-scores).

use greybox::estimate::{FitResult, PemOptions, fit};
use greybox::model::{DerivedEstimate, GreyBoxModel, Parameter, Prepared, Sensitivities, Signal};
use greybox::simulate::{SimOptions, simulate, visit_sensitivities};
use greybox::{Channel, Experiment, Result};

/// True thermal resistance winding → ambient [K/W].
const R_TH: f64 = 0.08;
/// True thermal capacity of the winding [J/K] (time constant R_th C_th = 960 s).
const C_TH: f64 = 12_000.0;
/// Sample time [s].
const H: f64 = 1.0;
/// Record length: four hours [samples].
const N: usize = 4 * 3600 + 1;
/// Measurement noise of the temperature [K].
const SIGMA: f64 = 0.2;

/// First-order thermal model; `analytic = false` hides the analytic sensitivities (the
/// estimator then takes finite differences), to check them.
struct Thermal {
    params: Vec<Parameter>,
    analytic: bool,
}

impl Thermal {
    fn new(analytic: bool) -> Self {
        let params = vec![Parameter::positive("r_th", "K/W", 0.1), Parameter::positive("c_th", "J/K", 1e4)];
        Self { params, analytic }
    }
}

/// Sample time and the held inputs, length N.
struct Inputs {
    h: f64,
    p_cu: Vec<f64>,
    t_amb: Vec<f64>,
}

/// Coefficients of the exact step and their derivatives.
struct Coefficients {
    r: f64,
    /// `a = exp(−h/(R C))`.
    a: f64,
    /// `1 − a`, without cancellation.
    one_minus_a: f64,
    /// `∂a/∂R = a h/(R² C)` [W/K].
    a_r: f64,
    /// `∂a/∂C = a h/(R C²)` [K/J].
    a_c: f64,
}

impl GreyBoxModel for Thermal {
    type Inputs = Inputs;
    type Coefficients = Coefficients;

    fn name(&self) -> &str {
        "winding_thermal"
    }
    fn n_states(&self) -> usize {
        1
    }
    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new("t_w", "K")]
    }
    fn input_channels(&self) -> Vec<String> {
        vec!["p_cu".into(), "t_amb".into()]
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn prepare(&self, e: &Experiment) -> Result<Inputs> {
        Ok(Inputs { h: e.h(), p_cu: e.channel("p_cu")?.to_vec(), t_amb: e.channel("t_amb")?.to_vec() })
    }
    fn coefficients(&self, theta: &[f64], inputs: &Inputs) -> Result<Coefficients> {
        let (r, c) = (theta[0], theta[1]);
        for (p, v) in self.params.iter().zip([r, c]) {
            if !(v.is_finite() && v > 0.0) {
                return Err(greybox::Error::InvalidParameter {
                    name: p.name.clone(),
                    value: v,
                    reason: "must be positive and finite".into(),
                });
            }
        }
        let x = inputs.h / (r * c);
        let a = (-x).exp();
        Ok(Coefficients { r, a, one_minus_a: -(-x).exp_m1(), a_r: a * x / r, a_c: a * x / c })
    }
    fn step(&self, c: &Coefficients, inp: &Inputs, k: usize, x: &[f64], x_next: &mut [f64]) {
        x_next[0] = c.a * x[0] + c.one_minus_a * (inp.t_amb[k] + c.r * inp.p_cu[k]);
    }
    fn sensitivities(&self) -> Option<&dyn Sensitivities<Inputs, Coefficients>> {
        if self.analytic { Some(self) } else { None }
    }
    /// Thermal time constant `τ = R_th C_th` [s], `σ_τ² = C² σ_R² + R² σ_C² + 2 R C cov(R, C)`.
    fn derived(&self, th: &[f64], cov: &[Vec<f64>]) -> Vec<DerivedEstimate> {
        let (r, c) = (th[0], th[1]);
        let var = c * c * cov[0][0] + r * r * cov[1][1] + 2.0 * r * c * cov[0][1];
        vec![DerivedEstimate::new("tau", "s", r * c, var.sqrt())]
    }
}

impl Sensitivities<Inputs, Coefficients> for Thermal {
    fn step_sensitivity(
        &self,
        c: &Coefficients,
        inp: &Inputs,
        k: usize,
        x: &[f64],
        s: &[f64],
        x_next: &mut [f64],
        s_next: &mut [f64],
    ) {
        // T⁺ = a T + (1 − a) u with u = T_amb + R P:
        // ∂T⁺/∂R = a s_R + ∂a/∂R (T − u) + (1 − a) P,  ∂T⁺/∂C = a s_C + ∂a/∂C (T − u).
        let u = inp.t_amb[k] + c.r * inp.p_cu[k];
        x_next[0] = c.a * x[0] + c.one_minus_a * u;
        s_next[0] = c.a * s[0] + c.a_r * (x[0] - u) + c.one_minus_a * inp.p_cu[k];
        s_next[1] = c.a * s[1] + c.a_c * (x[0] - u);
    }
    fn output_sensitivity(
        &self,
        _: &Coefficients,
        _: &Inputs,
        _: usize,
        _: &[f64],
        s: &[f64],
        dy: &mut [f64],
    ) {
        dy.copy_from_slice(&s[..2]);
    }
}

/// Small deterministic generator (xorshift64*), uniform in [0, 1) and standard normal.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Four hours of a load cycle: copper losses in steps of 2 to 20 minutes, idle a quarter
/// of the time, otherwise 200 to 1500 W; ambient drifting by ±4 K around 295 K. The winding
/// temperature starts at ambient and is integrated with RK4 (100 substeps per sample).
fn load_cycle(rng: &mut Rng) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut p_cu, mut t_amb) = (Vec::with_capacity(N), Vec::with_capacity(N));
    let (mut level, mut left) = (0.0, 0usize);
    for k in 0..N {
        if left == 0 {
            left = 120 + (rng.uniform() * 1080.0) as usize;
            level = if rng.uniform() < 0.25 { 0.0 } else { 200.0 + 1300.0 * rng.uniform() };
        }
        left -= 1;
        p_cu.push(level);
        let t = k as f64 * H;
        t_amb.push(295.0 + 4.0 * (2.0 * std::f64::consts::PI * t / (6.0 * 3600.0)).sin());
    }
    let mut t_w = vec![t_amb[0]];
    let dt = H / 100.0;
    for k in 0..N - 1 {
        let f = |t: f64| (p_cu[k] - (t - t_amb[k]) / R_TH) / C_TH;
        let mut t = t_w[k];
        for _ in 0..100 {
            let k1 = f(t);
            let k2 = f(t + 0.5 * dt * k1);
            let k3 = f(t + 0.5 * dt * k2);
            let k4 = f(t + dt * k3);
            t += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        t_w.push(t);
    }
    (p_cu, t_amb, t_w)
}

fn experiment(name: &str, p_cu: &[f64], t_amb: &[f64], t_w: Vec<f64>) -> Result<Experiment> {
    Experiment::try_new(
        name,
        H,
        vec![
            Channel::new("p_cu", "W", p_cu.to_vec()),
            Channel::new("t_amb", "K", t_amb.to_vec()),
            Channel::new("t_w", "K", t_w),
        ],
    )
}

/// `∂ŷ_k/∂θ` for every sample, row-major `N × n_θ`.
fn output_sensitivities(model: &Thermal, e: &Experiment, theta: &[f64]) -> Result<Vec<f64>> {
    let prep = Prepared::new(model, e)?;
    let mut out = Vec::with_capacity(prep.n * theta.len());
    visit_sensitivities(model, &prep, theta, &SimOptions::default(), |_, _, dy, _| {
        out.extend_from_slice(dy)
    })?;
    Ok(out)
}

/// Central difference of the simulated record, `(ŷ(θ + δ_j) − ŷ(θ − δ_j))/(2δ_j)` with
/// `δ_j = rel θ_j`, row-major `N × n_θ`.
fn record_difference(model: &Thermal, e: &Experiment, theta: &[f64], rel: f64) -> Result<Vec<f64>> {
    let prep = Prepared::new(model, e)?;
    let mut out = vec![0.0; prep.n * theta.len()];
    for j in 0..theta.len() {
        let d = rel * theta[j];
        let shifted = |sign: f64| {
            let mut t = theta.to_vec();
            t[j] += sign * d;
            simulate(model, &prep, &t, &SimOptions::default())
        };
        let (plus, minus) = (shifted(1.0)?, shifted(-1.0)?);
        for k in 0..prep.n {
            out[k * theta.len() + j] = (plus[k] - minus[k]) / (2.0 * d);
        }
    }
    Ok(out)
}

/// Prints the estimates against the truth (with z-scores when `z` is set); returns
/// (relative errors, z-scores).
fn report(label: &str, fit: &FitResult, show_z: bool) -> ([f64; 2], [f64; 2]) {
    let (mut rel, mut z) = ([0.0; 2], [0.0; 2]);
    println!("{label}: {} iterations, {}", fit.solver.iterations, fit.solver.termination);
    for (j, (name, truth)) in [("r_th", R_TH), ("c_th", C_TH)].into_iter().enumerate() {
        let p = fit.parameter(name).expect("estimated");
        rel[j] = ((p.value - truth) / truth).abs();
        z[j] = (p.value - truth) / p.std_error;
        let z_text = if show_z { format!(", z = (θ̂ − θ)/se = {:+.2}", z[j]) } else { String::new() };
        println!(
            "  {name} = {:.9e} ± {:.3e} {} (truth {truth:e}): relative error {:.2e}{z_text}",
            p.value, p.std_error, p.unit, rel[j]
        );
    }
    (rel, z)
}

fn main() -> Result<()> {
    let mut rng = Rng(0x7e57_c0de_2024_0001);
    let (p_cu, t_amb, t_w) = load_cycle(&mut rng);
    let peak = t_w.iter().fold(f64::MIN, |m, v| m.max(*v));
    println!(
        "log: {N} samples at h = {H} s ({:.1} h), P_cu 0–{:.0} W, T_w {:.1}–{peak:.1} K",
        (N - 1) as f64 * H / 3600.0,
        p_cu.iter().fold(0.0f64, |m, v| m.max(*v)),
        t_w.iter().fold(f64::MAX, |m, v| m.min(*v)),
    );
    let clean = experiment("clean", &p_cu, &t_amb, t_w.clone())?;
    let model = Thermal::new(true);
    let start = [0.05, 20_000.0];

    // 1. Analytic sensitivities against finite differences, at the start: the library's
    //    (the model without `sensitivities()`: a difference of every step, chained) and a
    //    central difference of the whole simulated record (relative step 3e-5).
    let analytic = output_sensitivities(&model, &clean, &start)?;
    let library_fd = output_sensitivities(&Thermal::new(false), &clean, &start)?;
    let record_fd = record_difference(&model, &clean, &start, 3e-5)?;
    let mut worst = [0.0f64; 2];
    for (m, (label, fd)) in
        [("library finite differences", &library_fd), ("record central difference", &record_fd)]
            .into_iter()
            .enumerate()
    {
        for (j, name) in ["r_th", "c_th"].into_iter().enumerate() {
            let col = |s: &[f64]| s.iter().skip(j).step_by(2).copied().collect::<Vec<f64>>();
            let (a, f) = (col(&analytic), col(fd));
            let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let diff = a.iter().zip(&f).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            println!(
                "∂t_w/∂{name}, analytic vs {label}: max difference {diff:.3e}, \
                 relative to max |∂t_w/∂{name}| = {scale:.3e}: {:.3e}",
                diff / scale
            );
            worst[m] = worst[m].max(diff / scale);
        }
    }
    println!(
        "max relative difference of the analytic sensitivities: {:.3e} against the library's finite \
         differences, {:.3e} against a central difference of the record",
        worst[0], worst[1]
    );
    assert!(worst[1] <= 1e-7, "analytic sensitivities disagree with finite differences: {worst:?}");
    // The library's differences are looser (see the top of the file), but far inside what a
    // Gauss-Newton step needs.
    assert!(worst[0] <= 1e-4, "library finite differences far from the analytic sensitivities: {worst:?}");

    // 2. Noise-free fit.
    let options = PemOptions::default();
    let exact = fit(&model, std::slice::from_ref(&clean), &start, &options)?;
    let (rel, _) = report("\nnoise-free fit", &exact, false);
    assert!(rel.iter().all(|r| *r <= 1e-6), "noise-free recovery: relative errors {rel:?}");

    // 3. Gaussian measurement noise σ on the temperature.
    let noisy_t: Vec<f64> = t_w.iter().map(|t| t + SIGMA * rng.normal()).collect();
    let noisy = experiment("noisy", &p_cu, &t_amb, noisy_t)?;
    let est = fit(&model, std::slice::from_ref(&noisy), &start, &options)?;
    let (_, z) = report(&format!("\nfit with σ = {SIGMA} K noise"), &est, true);
    println!("  rms residual {:.4} K (σ = {SIGMA} K)", est.fit.rms_residual[0]);
    // The time constant R_th C_th: its standard error needs the covariance (R and C are
    // strongly correlated from a temperature record), not the two standard errors alone.
    let tau = est.derived("tau").expect("the model derives tau");
    let z_tau = (tau.value - R_TH * C_TH) / tau.std_error;
    let naive = tau.value
        * ((est.parameters[0].std_error / R_TH).powi(2) + (est.parameters[1].std_error / C_TH).powi(2))
            .sqrt();
    println!(
        "  tau = {:.3} ± {:.3} s (truth {}), z = {z_tau:+.2}; ignoring the correlation would give ± {naive:.3} s",
        tau.value,
        tau.std_error,
        R_TH * C_TH
    );
    assert!(z_tau.abs() <= 3.0, "tau beyond 3 standard errors: z = {z_tau}");
    assert!(z.iter().all(|z| z.abs() <= 3.0), "estimates beyond 3 standard errors: z = {z:?}");
    println!("\n{est}");
    Ok(())
}

/// The example is also a test (`tests/it/examples.rs`): its assertions must hold.
#[cfg(test)]
#[test]
fn example_runs() {
    main().expect("the example runs");
}
