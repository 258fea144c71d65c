//! Monte Carlo coverage of the steady-state fit's 95 % intervals (issue 32): `N` noisy
//! drive-simulator logs (seeds 1..=N) of long holds at four speeds with a constant load and
//! d-current injection, decimated to a slow logger's rate by point samples, fitted by
//! [`steady_state`] at the drive's control period. Prints per parameter the fraction of
//! intervals that cover the truth, the mean and standard deviation of the standardised
//! error `(θ̂ − θ)/se` (0 and 1 when honest) and the mean relative error.
//!
//! Usage: `cargo run --release --example steady_coverage -- [N] [factor] [spm|ipm] [r_s] [given|estimated]`
//! (defaults 100, 100 (10 kHz → 100 Hz), spm, the motor's own R_s, the control period
//! given; `estimated`: the default fit, which estimates its effect as the nuisance `h_c2`).

use greybox::drive::{
    Control, DriveConfig, IPM_MOTOR, Mechanics, Profile, SPM_MOTOR, Sensors, scenario, simulate_drive,
};
use greybox::pmsm::{MotorKind, SteadyOptions, steady_state};

fn main() -> greybox::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: u64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(100);
    let factor: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(100);
    let ipm = args.get(2).is_some_and(|s| s == "ipm");
    let mut motor = if ipm { IPM_MOTOR } else { SPM_MOTOR };
    if let Some(r) = args.get(3).and_then(|s| s.parse().ok()) {
        motor.r_s = r;
    }
    let kind = if ipm { MotorKind::Ipm } else { MotorKind::Spm };
    let base = scenario("exp3", motor)?;
    let c = base.control.clone();
    let reference = Profile::back_and_forth(0.1, &[30.0, 100.0, 190.0, 280.0], 0.2, 3.0, 1.0);
    let mut i_d = vec![(0.0, 0.0)];
    for j in [1.0, 2.0] {
        let s = 0.1 + 7.8 * j;
        i_d.extend([(s + 0.3, 0.0), (s + 0.3, -0.3 * c.i_max), (s + 3.3, -0.3 * c.i_max), (s + 3.3, 0.0)]);
    }
    let mut cfg = DriveConfig {
        control: Control { reference, i_d: Profile(i_d), ..c.clone() },
        mechanics: Mechanics {
            gravity: 0.0,
            load: Profile::constant(0.2 * motor.k_t() * c.i_max),
            ..base.mechanics.clone()
        },
        sensors: Sensors { current_noise: 0.02, voltage_noise: 0.5, ..Default::default() },
        duration: 31.3,
        ..base
    };
    let given = args.get(4).is_none_or(|s| s != "estimated");
    let options = SteadyOptions { control_period: given.then_some(c.h), ..Default::default() };
    let mut z: Vec<Vec<f64>> = Vec::new();
    let mut errors: Vec<Vec<f64>> = Vec::new();
    let mut names = Vec::new();
    for seed in 1..=n {
        cfg.seed = seed;
        let log = simulate_drive(&cfg)?;
        let e = log.experiment.decimate(factor)?;
        let est = steady_state(&[e], motor.n_p, kind, &options)?;
        let truth = |name: &str| match name {
            "r_s" => motor.r_s,
            "l_s" | "l_d" => motor.l_d,
            "l_q" => motor.l_q,
            greybox::pmsm::PERIOD_TERM => c.h * c.h,
            _ => motor.k_e(),
        };
        names.clone_from(&est.names);
        z.resize(names.len(), Vec::new());
        errors.resize(names.len(), Vec::new());
        for (j, name) in est.names.iter().enumerate() {
            let t = truth(name);
            // The interval's own t quantile: coverage of [θ̂ ± ci95].
            z[j].push((est.theta[j] - t) / est.ci95[j] * 1.96);
            errors[j].push(est.theta[j] / t - 1.0);
        }
    }
    println!("{} logs, {}x decimated, {:?}, R_s {} ohm", n, factor, kind, motor.r_s);
    for (j, name) in names.iter().enumerate() {
        let m = z[j].len() as f64;
        let cover = z[j].iter().filter(|v| v.abs() <= 1.96).count() as f64 / m;
        let mean = z[j].iter().sum::<f64>() / m;
        let sd = (z[j].iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt();
        let rel = errors[j].iter().sum::<f64>() / m;
        println!("  {name:4} coverage {:.3}  z mean {mean:+.3} sd {sd:.3}  mean rel error {rel:+.3e}", cover);
    }
    Ok(())
}
