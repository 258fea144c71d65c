//! Predicted against realised standard errors (issue 32): for each plan, the design
//! prediction from one noise-free simulation, then `N` noisy simulations (seeds 1..=N)
//! fitted with `fit_pmsm`; prints predicted se, realised std and their ratio per
//! parameter. Usage: `cargo run --release --example design_check -- [N] [duration_s] [plans…]`.

use greybox::drive::design::predict_plan;
use greybox::drive::{SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{PmsmFitOptions, fit_pmsm};

fn main() -> greybox::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: u64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(20);
    let duration: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(4.0);
    let plans: Vec<String> =
        if args.len() > 2 { args[2..].to_vec() } else { vec!["exp3".into(), "exp5".into(), "exp6".into()] };
    for name in &plans {
        let mut cfg = scenario(name, SPM_MOTOR)?;
        cfg.duration = duration;
        cfg.sensors.current_noise =
            std::env::var("DESIGN_NOISE").ok().and_then(|s| s.parse().ok()).unwrap_or(0.05);
        // DESIGN_POLE=a: AR(1) current noise with pole a.
        cfg.sensors.current_noise_pole =
            std::env::var("DESIGN_POLE").ok().and_then(|s| s.parse().ok()).unwrap_or(0.0);
        let pred = predict_plan(&cfg)?;
        let p = &pred.prediction;
        println!(
            "{name}: {duration} s, cond {:.1}, D {:.3}, A {:.3e}, E {:.3e}",
            p.condition_number, p.d_criterion, p.a_criterion, p.e_criterion
        );
        let names: Vec<String> = p.parameters.iter().map(|q| q.name.clone()).collect();
        let mut draws: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
        for seed in 1..=n {
            cfg.seed = seed;
            let log = simulate_drive(&cfg)?;
            let fit = fit_pmsm(&[log.experiment], &PmsmFitOptions::new(cfg.motor.n_p))?;
            for (d, q) in draws.iter_mut().zip(&names) {
                d.push(fit.parameter(q).map_or(f64::NAN, |e| e.value));
            }
        }
        for ((q, d), pp) in names.iter().zip(&draws).zip(&p.parameters) {
            let m = d.iter().sum::<f64>() / d.len() as f64;
            let sd = (d.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (d.len() as f64 - 1.0)).sqrt();
            println!(
                "  {q:5} nominal {:.6e} mean {:.6e} predicted se {:.3e} realised sd {:.3e} ratio {:.3}",
                pp.value,
                m,
                pp.std_error,
                sd,
                sd / pp.std_error
            );
        }
    }
    Ok(())
}
