//! A fit of a very long record held in memory: `fit_pmsm` on a synthetic 10⁷-sample
//! surface-magnet log, with the fit time and the peak resident memory against the size of
//! the data it reads.
//!
//! The record is the drive simulator's `exp3` moves on `SPM_MOTOR` at 10 kHz, as in
//! `benches/scaling.rs` (the scenario repeats past its end: 10⁷ samples are 1000 s; no
//! noise, so the estimates must land on the truth). Only the five channels the fit reads
//! (`ud, uq, id, iq, w_m`, 8 bytes a value) are kept: they are "the data". After the
//! simulation the peak resident set size is reset (`5` written to /proc/self/clear_refs),
//! so the peak printed (VmHWM of /proc/self/status) is the fit's, data included; when the
//! reset is refused the output says that the peak includes the simulation. Off Linux the
//! memory figures are "unavailable". One voltage hold (`HoldChoice::Stator`), default
//! threads.
//!
//! Run: `cargo run --release --example large_record -- 10000000` (the argument is the
//! number of samples N, default 10⁷, at least 16).

use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{HoldChoice, PmsmFitOptions, fit_pmsm};
use greybox::{Channel, Experiment};
use std::time::Instant;

/// The value of `key` (`VmHWM`, `VmRSS`) in /proc/self/status [bytes]; `None` off Linux.
fn status_bytes(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key) && l[key.len()..].starts_with(':'))?;
    let kb: u64 = line[key.len() + 1..].trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kb * 1024)
}

fn mb(bytes: Option<u64>) -> String {
    bytes.map_or_else(|| "unavailable".to_string(), |b| format!("{:.1} MB", b as f64 / 1e6))
}

fn main() -> greybox::Result<()> {
    let bad = |reason: String| greybox::Error::InvalidOption { option: "N".into(), reason };
    let n: usize = match std::env::args().nth(1) {
        None => 10_000_000,
        Some(a) => a.parse().map_err(|_| bad(format!("`{a}` is not a number of samples")))?,
    };
    if n < 16 {
        return Err(bad(format!("{n} samples: a fit needs at least 16")));
    }

    // The drive simulator's record, cut down to the channels the fit reads.
    let t0 = Instant::now();
    let base = scenario("exp3", SPM_MOTOR)?;
    let cfg = DriveConfig { duration: (n - 1) as f64 * base.control.h, ..base };
    let log = simulate_drive(&cfg)?;
    let sim_s = t0.elapsed().as_secs_f64();
    let truth = [("r_s", log.truth.start.r_s), ("l_s", log.truth.start.l_d), ("k_e", log.truth.k_e)];
    let channels: Vec<Channel> = ["ud", "uq", "id", "iq", "w_m"]
        .iter()
        .map(|name| {
            log.experiment.get(name).cloned().ok_or_else(|| bad(format!("the drive log has no `{name}`")))
        })
        .collect::<greybox::Result<_>>()?;
    let experiment = Experiment::try_new("exp3-large", log.experiment.h(), channels)?;
    let varying = log.truth.time_varying;
    drop(log);
    let samples = experiment.len();
    let data_bytes: usize =
        experiment.channels().iter().map(|c| c.values.len() * std::mem::size_of::<f64>()).sum();
    let sim_peak = status_bytes("VmHWM");
    let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
    let rss_before = status_bytes("VmRSS");

    // The fit: least-squares start, stator hold, output error with estimated x0.
    let options = PmsmFitOptions { hold: HoldChoice::Stator, ..PmsmFitOptions::new(SPM_MOTOR.n_p) };
    let t1 = Instant::now();
    let fit = fit_pmsm(std::slice::from_ref(&experiment), &options)?;
    let fit_s = t1.elapsed().as_secs_f64();
    let peak = status_bytes("VmHWM");

    println!("samples N            {samples}");
    println!(
        "data                 {data_bytes} bytes ({:.1} MB: {} channels x N x 8 bytes)",
        data_bytes as f64 / 1e6,
        experiment.channels().len()
    );
    println!("simulation           {sim_s:.2} s (peak resident {} before the fit)", mb(sim_peak));
    println!(
        "fit                  {:.1} ms, {:.1} ns per sample ({} iterations, {} evaluations, {})",
        fit_s * 1e3,
        fit_s * 1e9 / samples as f64,
        fit.solver.iterations,
        fit.solver.evaluations,
        fit.solver.termination
    );
    println!("resident at fit start {}", mb(rss_before));
    let scope =
        if reset { "during the fit" } else { "of the whole run (peak reset refused): simulation included" };
    println!("peak resident        {} {scope}", mb(peak));
    match peak {
        Some(p) => println!("peak / data          {:.2}", p as f64 / data_bytes as f64),
        None => println!("peak / data          unavailable"),
    }
    if varying {
        println!("note: the plant varies within the record; the truth below is its start");
    }
    println!("{:<6} {:>22} {:>22} {:>12}", "param", "estimate", "truth", "rel. error");
    for (name, t) in truth {
        let v = fit.parameter(name).map_or(f64::NAN, |p| p.value);
        println!("{name:<6} {v:>22.15e} {t:>22.15e} {:>12.2e}", v / t - 1.0);
    }
    Ok(())
}
