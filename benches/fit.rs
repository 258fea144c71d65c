//! Criterion benches: one normal-equation pass (simulation with sensitivities) and a whole
//! fit on a development log.

use criterion::{Criterion, criterion_group};
use greybox::estimate::{PemProblem, ProblemOptions, scaling::NominalScaling};
use greybox::model::{GreyBoxModel, PmsmIpm, PmsmSpm, VoltageHold};
use greybox::pmsm::{HoldChoice, PmsmFitOptions, fit_pmsm};
use std::hint::black_box;
use std::path::PathBuf;

/// Folder of the development logs (not part of the repository): `$GREYBOX_SHARED_DATA`,
/// else `../shared/data` beside the repository.
fn shared_dir() -> PathBuf {
    match std::env::var_os("GREYBOX_SHARED_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
    }
}

fn log(stem: &str, n_p: u32) -> greybox::Experiment {
    let path = shared_dir().join(format!("{stem}.csv.gz"));
    greybox::read_csv(path, n_p, &Default::default()).expect("log")
}

fn pass<M: GreyBoxModel>(c: &mut Criterion, name: &str, model: &M, e: &greybox::Experiment, start: &[f64]) {
    for estimate_x0 in [false, true] {
        let name = format!("{name}{}", if estimate_x0 { ", x0 estimated" } else { "" });
        pass_with(c, &name, model, e, start, estimate_x0);
    }
}

fn pass_with<M: GreyBoxModel>(
    c: &mut Criterion,
    name: &str,
    model: &M,
    e: &greybox::Experiment,
    start: &[f64],
    estimate_x0: bool,
) {
    let prep = model.prepare(e).unwrap();
    let opts = ProblemOptions { estimate_x0, ..Default::default() };
    let problem = PemProblem::new(model, vec![(prep, None)], start, &NominalScaling, &opts).unwrap();
    let p = problem.start_vector(start);
    c.bench_function(&format!("{name}: normal equations, {} samples", e.len()), |b| {
        b.iter(|| black_box(problem.normal_equations(black_box(&p)).unwrap()))
    });
    c.bench_function(&format!("{name}: cost only, {} samples", e.len()), |b| {
        b.iter(|| black_box(problem.cost(black_box(&p)).unwrap()))
    });
    c.bench_function(&format!("{name}: statistics pass, {} samples", e.len()), |b| {
        b.iter(|| black_box(problem.sums(black_box(&p)).unwrap()))
    });
}

fn benches(c: &mut Criterion) {
    let servo = log("servo_spm_moves_idinj", 4);
    let ipm = log("ipm_moves_idinj", 2);
    pass(c, "spm stator hold", &PmsmSpm::new(VoltageHold::Stator), &servo, &[0.9, 4.5e-3, 0.54]);
    pass(c, "ipm stator hold", &PmsmIpm::new(VoltageHold::Stator), &ipm, &[0.35, 3.2e-3, 7.5e-3, 0.42]);
    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
    g.bench_function("spm fit servo_spm_moves_idinj (LS start, stator hold)", |b| {
        let o = PmsmFitOptions { hold: HoldChoice::Stator, ..Default::default() };
        b.iter(|| black_box(fit_pmsm(std::slice::from_ref(&servo), &o).unwrap()))
    });
    g.finish();
}

criterion_group!(fit, benches);

// `criterion_main!(fit)`, but skipping with one line when the development logs are absent.
fn main() {
    let dir = shared_dir();
    if !dir.is_dir() {
        eprintln!(
            "skipped benches/fit: {} not found (development logs are not part of the repository; \
             set GREYBOX_SHARED_DATA to their folder)",
            dir.display()
        );
        return;
    }
    fit();
    Criterion::default().configure_from_args().final_summary();
}
