//! A first design search (issue 32, WIP): scenarios × record lengths, the shortest plan
//! whose predicted 95 % half-width of R_s is within `target` (relative). Usage:
//! `cargo run --release --example design_search -- [current_noise_A] [target]`.

use greybox::drive::predict_plan;
use greybox::drive::{SPM_MOTOR, scenario};

fn main() -> greybox::Result<()> {
    let args: Vec<f64> = std::env::args().skip(1).filter_map(|s| s.parse().ok()).collect();
    let noise = args.first().copied().unwrap_or(0.05);
    let target = args.get(1).copied().unwrap_or(0.005);
    let mut best: Option<(f64, String)> = None;
    for name in ["exp3", "exp5", "exp6"] {
        for duration in [0.25, 0.5, 1.0, 2.0, 4.0, 8.0] {
            let mut cfg = scenario(name, SPM_MOTOR)?;
            cfg.duration = duration;
            cfg.sensors.current_noise = noise;
            let Ok(pred) = predict_plan(&cfg) else { continue };
            let r = pred.prediction.parameter("r_s").expect("r_s");
            let half = 1.96 * r.std_error / r.value;
            let ok = half <= target;
            println!(
                "{name} {duration:5.2} s: R_s ± {:.3} % (95 %){}",
                100.0 * half,
                if ok { "  reaches" } else { "" }
            );
            if ok && best.as_ref().is_none_or(|(d, _)| duration < *d) {
                best = Some((duration, name.into()));
            }
        }
    }
    match best {
        Some((d, n)) => println!("shortest: {n} at {d} s"),
        None => println!("no candidate reaches ±{} %", 100.0 * target),
    }
    Ok(())
}
