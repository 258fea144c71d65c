//! The saturating IPM of the drive simulator (`greybox::drive::IPM_SATURATION`) under
//! increasing load: the linear IPM fit's `L_d`, `L_q`, `K_e` per load (their bias grows with
//! the load) and the saturated fit's coefficients with their 95 % intervals against the
//! truth, noise-free and with current noise.
//!
//! Run: `cargo run --release --example saturation -- [seeds] [current noise σ, A]`

use greybox::drive::{IPM_SATURATION, SATURATED_IPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{PmsmFitOptions, fit_saturated};

fn main() -> greybox::Result<()> {
    let seeds: u64 = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(0);
    let sigma: f64 = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(0.05);
    let truth = IPM_SATURATION;
    let mut theta = vec![SATURATED_IPM_MOTOR.r_s];
    theta.extend(truth.theta());
    for (noise, runs) in [(0.0, 1), (sigma, seeds.max(1))] {
        let mut covered = vec![0usize; 7];
        for seed in 0..runs {
            for load in [0.0, 2.0, 4.0] {
                let mut cfg = scenario("exp3", SATURATED_IPM_MOTOR)?;
                cfg.saturation = Some(truth);
                cfg.duration = 3.0;
                cfg.mechanics.load = greybox::drive::Profile(vec![(0.0, load)]);
                cfg.sensors.current_noise = noise;
                cfg.seed = seed + 1;
                let log = simulate_drive(&cfg)?;
                let options = PmsmFitOptions::new(SATURATED_IPM_MOTOR.n_p);
                let fit = fit_saturated(&[log.experiment], &options, truth.exponents)?;
                let lin = |n: &str| fit.linear.parameter(n).map_or(f64::NAN, |p| p.value);
                if seed == 0 {
                    println!(
                        "noise {noise} A, load {load} N m: linear l_d {:.3} mH, l_q {:.3} mH, k_e {:.5} (truth k_e {:.5}); saturated fit {} iterations, {} substeps",
                        1e3 * lin("l_d"),
                        1e3 * lin("l_q"),
                        lin("k_e"),
                        f64::from(SATURATED_IPM_MOTOR.n_p) * truth.psi_f / (2.0f64 / 3.0).sqrt(),
                        fit.fit.solver.iterations,
                        fit.substeps
                    );
                }
                for (j, (p, t)) in fit.fit.parameters.iter().zip(&theta).enumerate() {
                    let inside = p.ci95[0] <= *t && *t <= p.ci95[1];
                    covered[j] += usize::from(inside);
                    if seed == 0 {
                        println!(
                            "  {:<6} {:>12.6e} ± {:>9.3e}  truth {:>12.6e}  rel err {:+.2e} {}",
                            p.name,
                            p.value,
                            p.std_error,
                            t,
                            p.value / t - 1.0,
                            if inside { "" } else { "OUTSIDE" }
                        );
                    }
                }
            }
        }
        println!("noise {noise}: coverage of 95 % intervals over {} fits: {covered:?}", 3 * runs);
    }
    Ok(())
}
