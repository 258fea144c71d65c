//! Criterion benches on records from the drive simulator (no files needed): one simulation
//! (SPM, IPM); one pass of each kind (cost, normal equations, statistics in full and after
//! a normal-equation pass at the same point, as a fit has it; SPM, stator hold,
//! x0 estimated, single-threaded) and the core prediction-error fit from the least-squares
//! start (`estimate::fit`, x0 estimated, one hold) at 60 800 and 512 000 samples; the whole
//! `fit_pmsm` (one hold and `--hold auto`, single-threaded and with the default thread
//! pool); the drive simulator itself (the log readers: `benches/read.rs`).
//!
//! Run: `cargo bench --bench scaling` (`GREYBOX_BENCH_10M=1` adds the 10⁷-sample record to
//! the passes and the core fit).

use criterion::{Criterion, criterion_group};
use greybox::Experiment;
use greybox::drive::{DriveConfig, IPM_MOTOR, SPM_MOTOR, scenario, simulate_drive};
use greybox::estimate::{NominalScaling, PemOptions, PemProblem, ProblemOptions};
use greybox::model::Prepared;
use greybox::pmsm::{
    HoldChoice, MotorKind, PmsmFitOptions, PmsmIpm, PmsmSpm, VoltageHold, fit_pmsm, least_squares,
};
use greybox::simulate::{SimOptions, simulate};
use std::hint::black_box;

/// The exp3 moves on `motor`, `n` samples at 10 kHz (the scenario repeats past its end).
fn record(motor: greybox::pmsm::MotorParameters, n: usize) -> Experiment {
    let cfg = DriveConfig { duration: (n - 1) as f64 * 1e-4, ..scenario("exp3", motor).unwrap() };
    simulate_drive(&cfg).unwrap().experiment
}

fn options(model: MotorKind, n_p: u32, hold: HoldChoice) -> PmsmFitOptions {
    PmsmFitOptions { model, hold, ..PmsmFitOptions::new(n_p) }
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

    let big = record(SPM_MOTOR, 512_000);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let huge = std::env::var_os("GREYBOX_BENCH_10M").map(|_| record(SPM_MOTOR, 10_000_000));
    let mut records = vec![(&spm, "60800"), (&big, "512000")];
    if let Some(h) = &huge {
        records.push((h, "10000000"));
    }
    let m = PmsmSpm::new(SPM_MOTOR.n_p, VoltageHold::Stator);
    let mut g = c.benchmark_group("pass");
    g.sample_size(10);
    for &(e, n) in &records {
        let start = least_squares(std::slice::from_ref(e), SPM_MOTOR.n_p, MotorKind::Spm).unwrap().theta;
        let prep = Prepared::new(&m, e).unwrap();
        let opts = ProblemOptions { estimate_x0: true, ..Default::default() };
        let problem = PemProblem::new(&m, vec![(prep, None)], &start, &NominalScaling, &opts).unwrap();
        let p = problem.start_vector(&start);
        g.bench_function(format!("cost, {n} samples, 1 thread"), |b| {
            b.iter(|| one.install(|| black_box(problem.cost(black_box(&p)).unwrap())))
        });
        g.bench_function(format!("normal equations, {n} samples, 1 thread"), |b| {
            b.iter(|| one.install(|| black_box(problem.normal_equations(black_box(&p)).unwrap())))
        });
        // A problem that has run no normal-equation pass: the statistics pass in full.
        let fresh =
            PemProblem::new(&m, vec![(Prepared::new(&m, e).unwrap(), None)], &start, &NominalScaling, &opts)
                .unwrap();
        g.bench_function(format!("statistics, {n} samples, 1 thread"), |b| {
            b.iter(|| one.install(|| black_box(fresh.sums(black_box(&p)).unwrap())))
        });
        // As in a fit: the normal-equation pass at p (above) is the lowest-cost one met, so
        // its Grams serve and only the residuals are simulated. The pass runs here too, so
        // that a filter selecting this bench alone measures the same thing.
        one.install(|| problem.normal_equations(&p).unwrap());
        g.bench_function(format!("statistics after the normal equations at p, {n} samples, 1 thread"), |b| {
            b.iter(|| one.install(|| black_box(problem.sums(black_box(&p)).unwrap())))
        });
    }
    g.finish();
    let mut g = c.benchmark_group("core fit");
    g.sample_size(10);
    for &(e, n) in &records {
        let start = least_squares(std::slice::from_ref(e), SPM_MOTOR.n_p, MotorKind::Spm).unwrap().theta;
        // As `fit_pmsm` from its least-squares start: a close start's damping.
        let o = PemOptions {
            estimate_x0: true,
            initial_damping: Some(greybox::estimate::CLOSE_START_DAMPING),
            ..Default::default()
        };
        g.bench_function(
            format!("spm {n} samples from the LS start, stator hold, x0 estimated, 1 thread"),
            |b| {
                b.iter(|| {
                    one.install(|| {
                        black_box(greybox::estimate::fit(&m, std::slice::from_ref(e), &start, &o).unwrap())
                    })
                })
            },
        );
    }
    g.finish();

    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
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
