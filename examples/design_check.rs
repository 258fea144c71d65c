//! Predicted against realised standard errors (issue 32): for each plan (a thesis scenario
//! a named planned injection, `greybox::drive::PLANS`, or a scenario file `*.json`
//! such as `greybox design --search --best-config` writes), the design prediction from
//! one noise-free simulation, then `N` noisy simulations (seeds 1..=N) fitted with
//! `fit_pmsm`; prints predicted se, realised sd and their ratio per parameter as Markdown
//! rows, then the plans ranked by the predicted D-criterion and by the realised one
//! (`log det` of the inverse sample covariance of the relative estimates).
//! Usage: `cargo run --release --example design_check -- [N] [duration_s] [plans…]`;
//! `DESIGN_NOISE` (phase σ \[A\], default 0.05) and `DESIGN_POLE` (AR(1) pole, default 0).

use greybox::drive::SPM_MOTOR;
use greybox::drive::planned_drive;
use greybox::drive::predict_plan;
use greybox::drive::simulate_drive;
use greybox::pmsm::{PmsmFitOptions, fit_pmsm};
use nalgebra::DMatrix;

fn main() -> greybox::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: u64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(20);
    let duration: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(4.0);
    let plans: Vec<String> =
        if args.len() > 2 { args[2..].to_vec() } else { vec!["exp3".into(), "exp5".into(), "exp6".into()] };
    let env = |k: &str, d: f64| std::env::var(k).ok().and_then(|s| s.parse().ok()).unwrap_or(d);
    let mut ranks = Vec::new();
    println!("| plan | cond | D | param | predicted se | realised sd | ratio |");
    println!("|---|---|---|---|---|---|---|");
    for name in &plans {
        let mut cfg = if name.ends_with(".json") {
            let text = std::fs::read_to_string(name)
                .map_err(|source| greybox::Error::Io { path: name.into(), source })?;
            serde_json::from_str::<greybox::drive::DriveConfig>(&text).map_err(|e| {
                greybox::Error::InvalidOption { option: "config".into(), reason: e.to_string() }
            })?
        } else {
            planned_drive(name, SPM_MOTOR)?
        };
        cfg.duration = duration;
        cfg.sensors.current_noise = env("DESIGN_NOISE", 0.05);
        cfg.sensors.current_noise_pole = env("DESIGN_POLE", 0.0);
        let pred = predict_plan(&cfg)?;
        let p = &pred.prediction;
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
        let m = names.len();
        let mean: Vec<f64> = draws.iter().map(|d| d.iter().sum::<f64>() / d.len() as f64).collect();
        // Sample covariance of the relative estimates θ̂/θ.
        let cov = DMatrix::from_fn(m, m, |a, b| {
            let (va, vb) = (p.parameters[a].value, p.parameters[b].value);
            draws[a]
                .iter()
                .zip(&draws[b])
                .map(|(x, y)| (x - mean[a]) * (y - mean[b]) / (va * vb))
                .sum::<f64>()
                / (n as f64 - 1.0)
        });
        let realised_d = -cov.determinant().ln();
        for (j, (q, pp)) in names.iter().zip(&p.parameters).enumerate() {
            let sd = (cov[(j, j)]).sqrt() * pp.value.abs();
            let head = if j == 0 {
                format!(
                    "| {name} | {:.1} | {:.3} (realised {realised_d:.3})",
                    p.condition_number, p.d_criterion
                )
            } else {
                "| | |".to_string()
            };
            println!(
                "{head} | {q} | {:.4e} | {:.4e} | {:.3} |  mean {:.6e}",
                pp.std_error,
                sd,
                sd / pp.std_error,
                mean[j]
            );
        }
        eprintln!(
            "{name}: limits used: current {:.3}, voltage {:.3}",
            pred.limits.current, pred.limits.voltage
        );
        ranks.push((name.clone(), p.d_criterion, realised_d));
    }
    let order = |key: fn(&(String, f64, f64)) -> f64| {
        let mut v = ranks.clone();
        v.sort_by(|a, b| key(b).total_cmp(&key(a)));
        v.iter().map(|r| r.0.clone()).collect::<Vec<_>>().join(" > ")
    };
    println!("D-ranking predicted: {}", order(|r| r.1));
    println!("D-ranking realised:  {}", order(|r| r.2));
    Ok(())
}
