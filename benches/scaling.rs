//! Criterion benches on records from the drive simulator (no files needed): one simulation
//! (SPM, IPM), a whole fit from the least-squares start at 60 800 and 512 000 samples (one
//! hold and `--hold auto`, single-threaded and with the default thread pool), the drive
//! simulator itself (the log readers: `benches/read.rs`).
//!
//! Run: `cargo bench --bench scaling` (`GREYBOX_BENCH_10M=1` adds a 10⁷-sample fit).

use criterion::{Criterion, criterion_group};
use greybox::Experiment;
use greybox::drive::{DriveConfig, IPM_MOTOR, SPM_MOTOR, scenario, simulate_drive};
use greybox::model::Prepared;
use greybox::pmsm::{HoldChoice, MotorKind, PmsmFitOptions, PmsmIpm, PmsmSpm, VoltageHold, fit_pmsm};
use greybox::simulate::{SimOptions, simulate};
use std::hint::black_box;

/// The exp3 moves on `motor`, `n` samples at 10 kHz (the scenario repeats past its end).
fn record(motor: greybox::pmsm::MotorParameters, n: usize) -> Experiment {
    let cfg = DriveConfig { duration: (n - 1) as f64 * 1e-4, ..scenario("exp3", motor).unwrap() };
    simulate_drive(&cfg).unwrap().experiment
}

fn options(model: MotorKind, n_p: u32, hold: HoldChoice) -> PmsmFitOptions {
    PmsmFitOptions { pole_pairs: n_p, model, hold, ..Default::default() }
}

fn benches(c: &mut Criterion) {
    let spm = record(SPM_MOTOR, 60_800);
    let ipm = record(IPM_MOTOR, 60_800);
    let mut g = c.benchmark_group("simulate");
    g.sample_size(20);
    let m = PmsmSpm::new(SPM_MOTOR.n_p, VoltageHold::Stator);
    let prep = Prepared::new(&m, &spm).unwrap();
    let theta = [SPM_MOTOR.r_s, SPM_MOTOR.l_d, SPM_MOTOR.k_e()];
    g.bench_function("spm, 60800 samples", |b| {
        b.iter(|| black_box(simulate(&m, &prep, black_box(&theta), &SimOptions::default()).unwrap()))
    });
    let m = PmsmIpm::new(IPM_MOTOR.n_p, VoltageHold::Stator);
    let prep = Prepared::new(&m, &ipm).unwrap();
    let theta = [IPM_MOTOR.r_s, IPM_MOTOR.l_d, IPM_MOTOR.l_q, IPM_MOTOR.k_e()];
    g.bench_function("ipm, 60800 samples", |b| {
        b.iter(|| black_box(simulate(&m, &prep, black_box(&theta), &SimOptions::default()).unwrap()))
    });
    g.finish();

    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
    let big = record(SPM_MOTOR, 512_000);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    for (e, n) in [(&spm, "60800"), (&big, "512000")] {
        for (hold, h) in [(HoldChoice::Stator, "stator hold"), (HoldChoice::Auto, "auto hold")] {
            let o = options(MotorKind::Spm, SPM_MOTOR.n_p, hold);
            g.bench_function(format!("spm {n} samples, {h}, 1 thread"), |b| {
                b.iter(|| one.install(|| black_box(fit_pmsm(std::slice::from_ref(e), &o).unwrap())))
            });
            g.bench_function(format!("spm {n} samples, {h}, default threads"), |b| {
                b.iter(|| black_box(fit_pmsm(std::slice::from_ref(e), &o).unwrap()))
            });
        }
    }
    let o = options(MotorKind::Ipm, IPM_MOTOR.n_p, HoldChoice::Stator);
    g.bench_function("ipm 60800 samples, stator hold", |b| {
        b.iter(|| black_box(fit_pmsm(std::slice::from_ref(&ipm), &o).unwrap()))
    });
    if std::env::var_os("GREYBOX_BENCH_10M").is_some() {
        let huge = record(SPM_MOTOR, 10_000_000);
        let o = options(MotorKind::Spm, SPM_MOTOR.n_p, HoldChoice::Stator);
        g.bench_function("spm 10000000 samples, stator hold", |b| {
            b.iter(|| black_box(fit_pmsm(std::slice::from_ref(&huge), &o).unwrap()))
        });
    }
    g.bench_function("drive simulator, 60800 samples (exp3, SPM)", |b| {
        b.iter(|| black_box(record(SPM_MOTOR, 60_800)))
    });
    g.finish();
}

criterion_group!(scaling, benches);

fn main() {
    scaling();
    Criterion::default().configure_from_args().final_summary();
}
