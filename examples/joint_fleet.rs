//! A joint fit of a fleet of logs of one motor type: shared K_e and L_s, one R_s per log
//! (`per_experiment = ["r_s"]`, as `greybox fit LOGS… -p 4 --per-log r_s`) and each log's
//! initial state, over the first N logs of a folder; with its time, its peak memory, the
//! share of the structured solve (`estimate::arrowhead`, the Schur complement and `faer`'s
//! Cholesky of the reduced system) and the shared K_e against the mean of per-log fits.
//!
//! Run: `cargo run --release --example joint_fleet -- DIR N [--per-log-fits]
//! [--structured-above K]` with DIR a (`.parquet`, `.csv`, `.csv.gz`; the first N in name order are fitted).
//! Logs like the measurement's (exp3 moves, 60 001 samples at 10 kHz, R_s of copper at
//! 20–100 °C, 0.02 A current noise):
//!
//! ```text
//! greybox simulate --scenario exp3 --duration 6 --seed I --set motor.r_s=R \
//!     --set sensors.current_noise=0.02 -o DIR/logI.parquet
//! ```
//!
//! `--structured-above K` keeps the sums by arrowhead blocks above K free parameters (0:
//! always; default 64, `PemOptions::structured_above`). With `--per-log-fits` every log is also fitted alone (in parallel) after the joint fit,
//! and the mean of their K_e and standard errors printed. The peak memory printed (VmHWM
//! of /proc/self/status, Linux) is read before those fits: the joint fit's, logs included.

use greybox::estimate::solve_timing;
use greybox::pmsm::{PmsmFitOptions, fit_pmsm, read_log};
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

/// The value of `key` (`VmHWM`) in /proc/self/status [bytes]; `None` off Linux.
fn status_bytes(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key) && l[key.len()..].starts_with(':'))?;
    let kb: u64 = line[key.len() + 1..].trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kb * 1024)
}

fn main() -> greybox::Result<()> {
    let bad = |reason: String| greybox::Error::InvalidOption { option: "joint_fleet".into(), reason };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(dir), Some(n)) = (args.first(), args.get(1)) else {
        return Err(bad("usage: joint_fleet DIR N [--per-log-fits]".into()));
    };
    let n: usize = n.parse().map_err(|_| bad(format!("`{n}` is not a number of logs")))?;
    let per_log_fits = args.iter().any(|a| a == "--per-log-fits");
    let structured_above = match args.iter().position(|a| a == "--structured-above") {
        None => None,
        Some(i) => {
            let k = args.get(i + 1).ok_or_else(|| bad("--structured-above needs a number".into()))?;
            Some(k.parse().map_err(|_| bad(format!("`{k}` is not a number of parameters")))?)
        }
    };
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| bad(format!("{dir}: {e}")))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let s = p.to_string_lossy();
            s.ends_with(".parquet") || s.ends_with(".csv") || s.ends_with(".csv.gz")
        })
        .collect();
    paths.sort();
    if paths.len() < n {
        return Err(bad(format!("{dir} holds {} logs, {n} asked for", paths.len())));
    }
    paths.truncate(n);

    let t0 = Instant::now();
    let logs = paths.iter().map(|p| read_log(p, &Default::default())).collect::<greybox::Result<Vec<_>>>()?;
    let read_s = t0.elapsed().as_secs_f64();
    let samples: usize = logs.iter().map(|l| l.len()).sum();
    let options = PmsmFitOptions {
        pem: greybox::estimate::PemOptions {
            per_experiment: vec!["r_s".into()],
            structured_above,
            ..Default::default()
        },
        ..PmsmFitOptions::new(4)
    };
    let before = solve_timing();
    let t1 = Instant::now();
    let fit = fit_pmsm(&logs, &options)?;
    let fit_s = t1.elapsed().as_secs_f64();
    let solve = solve_timing();
    let peak = status_bytes("VmHWM");
    let report = &fit.report;
    let k_e = report.parameter("k_e").ok_or_else(|| bad("no k_e in the report".into()))?;
    let free = report.parameters.iter().filter(|p| !p.fixed).count() + report.initial_states.len();
    println!("logs {n}, samples {samples}, free parameters {free}");
    println!("read {read_s:.2} s, joint fit {fit_s:.2} s ({}; {})", report.solver.termination, fit.hold);
    let (total, reduced) = (solve.total_s - before.total_s, solve.reduced_s - before.reduced_s);
    println!(
        "structured solves: {} in {total:.4} s ({:.3} % of the fit), of it faer's reduced system {reduced:.5} s ({:.4} %)",
        solve.solves - before.solves,
        100.0 * total / fit_s,
        100.0 * reduced / fit_s
    );
    println!("peak memory {:.1} MB", peak.map_or(f64::NAN, |b| b as f64 / 1e6));
    println!("shared k_e {:.7} ± {:.2e} V s/rad ({:?})", k_e.value, k_e.std_error, report.uncertainty.method);
    let r: Vec<f64> = report.parameters.iter().filter(|p| p.name == "r_s").map(|p| p.value).collect();
    let (lo, hi) = r.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
    println!("per-log r_s: {} from {lo:.4} to {hi:.4} Ω", r.len());

    if per_log_fits {
        let t2 = Instant::now();
        let single = PmsmFitOptions::new(4);
        let fits: Vec<(f64, f64)> = logs
            .par_iter()
            .map(|l| {
                let f = fit_pmsm(std::slice::from_ref(l), &single)?;
                let k = f.report.parameter("k_e").map_or((f64::NAN, f64::NAN), |p| (p.value, p.std_error));
                Ok(k)
            })
            .collect::<greybox::Result<_>>()?;
        let m = fits.len() as f64;
        let mean = fits.iter().map(|f| f.0).sum::<f64>() / m;
        let sd = (fits.iter().map(|f| (f.0 - mean).powi(2)).sum::<f64>() / (m - 1.0).max(1.0)).sqrt();
        let se = fits.iter().map(|f| f.1).sum::<f64>() / m;
        println!(
            "per-log fits ({:.1} s): mean k_e {mean:.7}, spread {sd:.2e}, mean se {se:.2e} (se/√N {:.2e})",
            t2.elapsed().as_secs_f64(),
            se / m.sqrt()
        );
    }
    Ok(())
}
