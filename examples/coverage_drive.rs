//! Monte-Carlo coverage of the reported 95 % intervals on closed-loop drive logs with the
//! noise real logs carry (the long run behind `tests/it/coverage_drive.rs`):
//! `cargo run --release --example coverage_drive [-- REALISATIONS [DURATION_S [CASE]]]`
//! (default 200 realisations of the thesis' exp3, 7.2 s, 72 001 samples; CASE, e.g. `(a)`,
//! runs the cases whose label starts with it).
//!
//! Each realisation is `greybox simulate --scenario exp3 --seed r` with one kind of noise,
//! fitted with the default options (`fit_pmsm`: least-squares start, automatic hold, output
//! error). Per case and parameter the table shows the bias against the truth, the spread of
//! the estimates against the mean reported standard error (`sd/se`, 1 when the error is
//! honest), the mean white-noise standard error (`std_error_white`), how often the reported
//! 95 % interval holds the truth, the bias in standard errors, and how many fits took the
//! batch-means covariance (residuals not white):
//!
//! - (a) white current noise σ = 0.05 A on each phase;
//! - (b) 1 V white noise on the logged voltages (errors in variables: output error is
//!   biased; the table gives the bias against the standard error);
//! - (c) AR(1) current noise with pole 0.9, stationary σ = 0.05 A;
//! - (d) both (a) and (b);
//! - (e) 1 V on the voltages and 0.03 A on the currents (issue 43's Monte Carlo).
//!
//! (a), (b), (d) and (e) are fitted by output error (`pem`, `--method pem`) and by
//! instrumental variables (`iv`, `--method iv`); (b), (d) and (e) also by the default
//! `auto` (output error, or instrumental variables where its fit finds the voltage noise
//! biasing it: `voltage_noise_bias`).

use greybox::drive::{SPM_MOTOR, scenario, simulate_drive};
use greybox::estimate::{CovarianceMethod, FitResult};
use greybox::pmsm::{Estimator, PmsmFitOptions, fit_pmsm_by};
use rayon::prelude::*;

const NAMES: [&str; 3] = ["r_s", "l_s", "k_e"];

/// One noise case: its label, the `--set` fields it changes and the method.
struct Case {
    label: &'static str,
    set: fn(&mut greybox::drive::DriveConfig),
    estimator: Estimator,
}

const PEM: Estimator = Estimator::PredictionError;
const IV: Estimator = Estimator::InstrumentalVariables;
const AUTO: Estimator = Estimator::Auto;

fn white_u(c: &mut greybox::drive::DriveConfig) {
    c.sensors.voltage_noise = 1.0;
}

fn both(c: &mut greybox::drive::DriveConfig) {
    c.sensors.voltage_noise = 1.0;
    c.sensors.current_noise = 0.05;
}

fn issue_43(c: &mut greybox::drive::DriveConfig) {
    c.sensors.voltage_noise = 1.0;
    c.sensors.current_noise = 0.03;
}

const CASES: [Case; 12] = [
    Case { label: "(a) white i, pem", set: |c| c.sensors.current_noise = 0.05, estimator: PEM },
    Case { label: "(a) white i, iv", set: |c| c.sensors.current_noise = 0.05, estimator: IV },
    Case { label: "(b) white u, pem", set: white_u, estimator: PEM },
    Case { label: "(b) white u, iv", set: white_u, estimator: IV },
    Case { label: "(b) white u, auto", set: white_u, estimator: AUTO },
    Case {
        label: "(c) AR(1) i, pem",
        set: |c| {
            c.sensors.current_noise = 0.05;
            c.sensors.current_noise_pole = 0.9;
        },
        estimator: PEM,
    },
    Case { label: "(d) u + i, pem", set: both, estimator: PEM },
    Case { label: "(d) u + i, iv", set: both, estimator: IV },
    Case { label: "(d) u + i, auto", set: both, estimator: AUTO },
    Case { label: "(e) 1 V + 0.03 A, pem", set: issue_43, estimator: PEM },
    Case { label: "(e) 1 V + 0.03 A, iv", set: issue_43, estimator: IV },
    Case { label: "(e) 1 V + 0.03 A, auto", set: issue_43, estimator: AUTO },
];

fn fit_one(case: &Case, seed: u64, duration: f64) -> greybox::Result<(FitResult, [f64; 3])> {
    let mut cfg = scenario("exp3", SPM_MOTOR)?;
    (case.set)(&mut cfg);
    cfg.seed = seed;
    cfg.duration = duration;
    let log = simulate_drive(&cfg)?;
    let m = log.truth.start;
    let truth = [m.r_s, m.l_d, log.truth.k_e];
    let opts = PmsmFitOptions::new(m.n_p);
    let fit = fit_pmsm_by(&[log.experiment], &opts, case.estimator)?;
    Ok((fit.report, truth))
}

fn main() -> greybox::Result<()> {
    let mut args = std::env::args().skip(1);
    let realisations: u64 = args.next().and_then(|a| a.parse().ok()).unwrap_or(200);
    let duration: f64 = args.next().and_then(|a| a.parse().ok()).unwrap_or(7.2);
    // Only the cases whose label starts with this (e.g. `(a)`), when given.
    let only = args.next().unwrap_or_default();
    let band = 1.96 * (0.95f64 * 0.05 / realisations as f64).sqrt() * 100.0;
    println!("exp3, {duration} s, {realisations} realisations; coverage expected 95 ± {band:.1} %");
    println!(
        "{:<24} {:<5} {:>11} {:>10} {:>10} {:>10} {:>6} {:>9} {:>9} {:>9}",
        "case",
        "param",
        "bias/truth",
        "sd(θ̂)",
        "mean se",
        "se white",
        "sd/se",
        "coverage",
        "bias/se",
        "batch m."
    );
    for case in CASES.iter().filter(|c| c.label.starts_with(&only)) {
        let fits: Vec<(FitResult, [f64; 3])> = (0..realisations)
            .into_par_iter()
            .map(|r| fit_one(case, r + 1, duration))
            .collect::<greybox::Result<_>>()?;
        let n = fits.len() as f64;
        let batch = fits.iter().filter(|(f, _)| f.uncertainty.method == CovarianceMethod::BatchMeans).count();
        for (j, name) in NAMES.iter().enumerate() {
            let rows: Vec<(f64, f64, f64, bool)> = fits
                .iter()
                .map(|(f, t)| {
                    let p = f.parameter(name).expect("a fitted parameter");
                    (p.value - t[j], p.std_error, p.std_error_white, p.ci95[0] <= t[j] && t[j] <= p.ci95[1])
                })
                .collect();
            let truth = fits[0].1[j];
            let bias = rows.iter().map(|r| r.0).sum::<f64>() / n;
            let sd = (rows.iter().map(|r| (r.0 - bias).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let se = rows.iter().map(|r| r.1).sum::<f64>() / n;
            let se_white = rows.iter().map(|r| r.2).sum::<f64>() / n;
            let hits = rows.iter().filter(|r| r.3).count();
            println!(
                "{:<24} {:<5} {:>+11.2e} {:>10.3e} {:>10.3e} {:>10.3e} {:>6.2} {:>8.1} % {:>+9.2} {:>9}",
                case.label,
                name,
                bias / truth,
                sd,
                se,
                se_white,
                sd / se,
                100.0 * hits as f64 / n,
                bias / se,
                batch
            );
        }
    }
    Ok(())
}
