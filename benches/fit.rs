//! Criterion benches: one normal-equation pass (simulation with sensitivities), the cost
//! alone and the statistics pass, a whole fit, and the whole default `greybox fit LOG -p 4`
//! through the application layer (read, setup checks, hold choice, fit, gate, report).
//!
//! With the development logs (`$GREYBOX_SHARED_DATA`, else `../shared/data` beside the
//! repository) the benches run on `servo_spm_moves_idinj` (SPM, 72 000 samples) and
//! `ipm_moves_idinj` (IPM), as they always have, and the switching-resolved PWM model's
//! passes on `servo_spm_pwm_deadtime_idinj` (72 000 samples fitted from the reference through
//! the inverter; dual numbers through 5 parameters, about 7 pieces a half period). Without
//! them the SPM benches run on the shipped `data/sample.csv.gz` (a 20 000-sample cut of the
//! same servo log) and one line says that the IPM and PWM benches were skipped.
//!
//! Run: `cargo bench --bench fit`

use criterion::{Criterion, criterion_group};
use greybox::Experiment;
use greybox::app::{FitRequest, PolePairs, fit_experiments, plan, read_sources};
use greybox::estimate::{NominalScaling, PemProblem, ProblemOptions};
use greybox::model::{GreyBoxModel, Prepared};
use greybox::pmsm::LogSource;
use greybox::pmsm::{
    HoldChoice, MotorKind, PmsmFitOptions, PmsmIpm, PmsmPwm, PmsmSetup, PmsmSpm, PwmInverter, VoltageHold,
    VoltageInput, fit_pmsm, read_log,
};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

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

/// The PWM-resolved model's normal equations and cost (the Jacobian passes in dual numbers
/// and the value-only passes of a fit's trial steps), from the reference at a 560 V link and
/// a 4096-level counter, at a start near the log's minimum (hard leg states, the predictor
/// restarting every period from the measured current).
fn pwm(c: &mut Criterion, shared: &Path) {
    let e = log(&shared.join("servo_spm_pwm_deadtime_idinj.csv.gz"));
    let setup = PmsmSetup { input: VoltageInput::REFERENCE, ..PmsmSetup::new(4, VoltageHold::Stator) };
    let inverter = PwmInverter { u_dc: Some(560.0), levels: Some(4096), ..Default::default() };
    let model = PmsmPwm::new(setup, MotorKind::Spm, inverter);
    let start = [0.9, 4.5e-3, 0.54, 3e-6, 1.0];
    let mut g = c.benchmark_group("pwm");
    g.sample_size(10);
    let prep = Prepared::new(&model, &e).unwrap();
    let problem =
        PemProblem::new(&model, vec![(prep, None)], &start, &NominalScaling, &Default::default()).unwrap();
    let p = problem.start_vector(&start);
    g.bench_function(format!("pwm spm: normal equations, {} samples", e.len()), |b| {
        b.iter(|| black_box(problem.normal_equations(black_box(&p)).unwrap()))
    });
    g.bench_function(format!("pwm spm: cost only, {} samples", e.len()), |b| {
        b.iter(|| black_box(problem.cost(black_box(&p)).unwrap()))
    });
    g.finish();
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
        pwm(c, &shared);
    }
    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
    g.bench_function(format!("spm fit {spm_stem} (LS start, stator hold)"), |b| {
        let o = PmsmFitOptions { hold: HoldChoice::Stator, ..PmsmFitOptions::new(4) };
        b.iter(|| black_box(fit_pmsm(std::slice::from_ref(&servo), &o).unwrap()))
    });
    // The command line's default fit as a whole, as `greybox fit LOG -p 4 --json` runs it:
    // the request planned, the log read, fitted with every check, the JSON and table made.
    let request = FitRequest::new(PolePairs::Given(4));
    let mut plan = plan(&request).unwrap();
    if let Some((options, ..)) = plan.pem.as_mut() {
        options.pem.progress = false;
    }
    g.bench_function(format!("greybox fit {spm_stem} -p 4, whole (read, checks, fit, report)"), |b| {
        b.iter(|| {
            let t0 = Instant::now();
            let logs = read_sources(&request.reading, &plan.csv, &[LogSource::Path(&spm_path)]).unwrap();
            let fitted = fit_experiments(&request, &plan, &logs, t0, t0.elapsed().as_secs_f64()).unwrap();
            black_box((fitted.json.len(), fitted.report().trusted()))
        })
    });
    g.finish();
}

criterion_group!(fit, benches);

fn main() {
    let shared = shared_dir();
    if !shared.is_dir() {
        eprintln!(
            "skipped the IPM and PWM benches of benches/fit: {} not found (development logs are not part of the \
             repository; set GREYBOX_SHARED_DATA to their folder); the SPM benches use data/sample.csv.gz",
            shared.display()
        );
    }
    fit();
    Criterion::default().configure_from_args().final_summary();
}
