//! Criterion benches: one normal-equation pass (simulation with sensitivities), the cost
//! alone and the statistics pass, and a whole fit.
//!
//! With the development logs (`$GREYBOX_SHARED_DATA`, else `../shared/data` beside the
//! repository) the benches run on `servo_spm_moves_idinj` (SPM, 72 000 samples) and
//! `ipm_moves_idinj` (IPM), as they always have. Without them the SPM benches run on the
//! shipped `data/sample.csv.gz` (a 20 000-sample cut of the same servo log) and one line
//! says that the IPM benches were skipped.
//!
//! Run: `cargo bench --bench fit`

use criterion::{Criterion, criterion_group};
use greybox::Experiment;
use greybox::estimate::{NominalScaling, PemProblem, ProblemOptions};
use greybox::model::{GreyBoxModel, Prepared};
use greybox::pmsm::{HoldChoice, PmsmFitOptions, PmsmIpm, PmsmSpm, VoltageHold, fit_pmsm, read_log};
use std::hint::black_box;
use std::path::{Path, PathBuf};

/// Folder of the development logs (not part of the repository): `$GREYBOX_SHARED_DATA`,
/// else `../shared/data` beside the repository.
fn shared_dir() -> PathBuf {
    match std::env::var_os("GREYBOX_SHARED_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
    }
}

fn log(path: &Path) -> Experiment {
    read_log(path, &Default::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn pass<M: GreyBoxModel>(c: &mut Criterion, name: &str, model: &M, e: &Experiment, start: &[f64]) {
    for estimate_x0 in [false, true] {
        let name = format!("{name}{}", if estimate_x0 { ", x0 estimated" } else { "" });
        pass_with(c, &name, model, e, start, estimate_x0);
    }
}

fn pass_with<M: GreyBoxModel>(
    c: &mut Criterion,
    name: &str,
    model: &M,
    e: &Experiment,
    start: &[f64],
    estimate_x0: bool,
) {
    let prep = Prepared::new(model, e).unwrap();
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
    let shared = shared_dir();
    let (spm_stem, spm_path) = if shared.is_dir() {
        ("servo_spm_moves_idinj", shared.join("servo_spm_moves_idinj.csv.gz"))
    } else {
        ("sample", PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/sample.csv.gz"))
    };
    let servo = log(&spm_path);
    pass(c, "spm stator hold", &PmsmSpm::new(4, VoltageHold::Stator), &servo, &[0.9, 4.5e-3, 0.54]);
    if shared.is_dir() {
        let ipm = log(&shared.join("ipm_moves_idinj.csv.gz"));
        let model = PmsmIpm::new(2, VoltageHold::Stator);
        pass(c, "ipm stator hold", &model, &ipm, &[0.35, 3.2e-3, 7.5e-3, 0.42]);
    }
    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
    g.bench_function(format!("spm fit {spm_stem} (LS start, stator hold)"), |b| {
        let o = PmsmFitOptions { hold: HoldChoice::Stator, ..PmsmFitOptions::new(4) };
        b.iter(|| black_box(fit_pmsm(std::slice::from_ref(&servo), &o).unwrap()))
    });
    g.finish();
}

criterion_group!(fit, benches);

fn main() {
    let shared = shared_dir();
    if !shared.is_dir() {
        eprintln!(
            "skipped the IPM benches of benches/fit: {} not found (development logs are not part of the \
             repository; set GREYBOX_SHARED_DATA to their folder); the SPM benches use data/sample.csv.gz",
            shared.display()
        );
    }
    fit();
    Criterion::default().configure_from_args().final_summary();
}
