//! Rough cost of one IPM step, without criterion: `cargo run --release --example ipm_step_timing`.
//!
//! Times 10⁶ calls of `step` and of `step_sensitivity` of `PmsmIpm` and `PmsmSpm` (both
//! holds) on a synthetic log (speed up to 250 rad/s mechanical, `n_p = 2`, `h = 200 µs`)
//! and prints nanoseconds per call. `step_sensitivity` is timed twice: called directly
//! (static dispatch, inlined) and through `GreyBoxModel::sensitivities()`, the
//! `&dyn Sensitivities` the estimator uses. A measurement, not a benchmark: no statistics.

use greybox::Experiment;
use greybox::model::{GreyBoxModel, Prepared, Sensitivities};
use greybox::pmsm::{DqSignals, PmsmIpm, PmsmSpm, VoltageHold};
use std::hint::black_box;
use std::time::Instant;

const N: usize = 1_000_000;
const N_P: u32 = 2;

fn log() -> Experiment {
    let h = 2e-4;
    let t = |k: usize| k as f64 * h;
    let signals = DqSignals {
        u_d: (0..N).map(|k| -20.0 + 5.0 * (50.0 * t(k)).sin()).collect(),
        u_q: (0..N).map(|k| 60.0 + 10.0 * (30.0 * t(k)).cos()).collect(),
        i_d: vec![-3.0; N],
        i_q: vec![8.0; N],
        w_m: (0..N).map(|k| 250.0 * (2.0 * t(k)).sin()).collect(),
        ..DqSignals::default()
    };
    signals.into_experiment("timing", h).expect("valid log")
}

fn time<M>(label: &str, m: &M, e: &Experiment, theta: &[f64])
where
    M: GreyBoxModel + Sensitivities<M::Inputs, M::Coefficients>,
{
    let p = Prepared::new(m, e).expect("prepare");
    let c = m.coefficients(theta, &p.inputs).expect("valid θ");
    let nt = theta.len();
    let (mut x, mut xn) = ([p.x0[0], p.x0[1]], [0.0; 2]);
    let start = Instant::now();
    for k in 0..p.n - 1 {
        m.step(&c, &p.inputs, k, black_box(&x), &mut xn);
        x = xn;
    }
    let ns_step = start.elapsed().as_secs_f64() * 1e9 / (p.n - 1) as f64;
    black_box(x);
    let dynamic = m.sensitivities().expect("the built-in models have analytic sensitivities");
    let direct = sweep(p.n, nt, x, |k, x, s, xn, sn| m.step_sensitivity(&c, &p.inputs, k, x, s, xn, sn));
    let through_dyn =
        sweep(p.n, nt, x, |k, x, s, xn, sn| dynamic.step_sensitivity(&c, &p.inputs, k, x, s, xn, sn));
    println!(
        "{label:<14} step {ns_step:7.1} ns   step_sensitivity {direct:7.1} ns   \
         (through &dyn Sensitivities {through_dyn:7.1} ns)"
    );
}

/// Nanoseconds per call of `f(k, x, s, x_next, s_next)` over the N − 1 intervals of a record
/// of n samples, from state `x` and zero sensitivity (n_θ = `nt`).
fn sweep(
    n: usize,
    nt: usize,
    mut x: [f64; 2],
    mut f: impl FnMut(usize, &[f64], &[f64], &mut [f64], &mut [f64]),
) -> f64 {
    let (mut s, mut sn) = (vec![0.0; 2 * nt], vec![0.0; 2 * nt]);
    let mut xn = [0.0; 2];
    let start = Instant::now();
    for k in 0..n - 1 {
        f(k, black_box(&x), &s, &mut xn, &mut sn);
        x = xn;
        std::mem::swap(&mut s, &mut sn);
    }
    let ns = start.elapsed().as_secs_f64() * 1e9 / (n - 1) as f64;
    black_box((x, &s));
    ns
}

fn main() {
    let e = log();
    for hold in [VoltageHold::Dq, VoltageHold::Stator] {
        time(&format!("ipm {hold}"), &PmsmIpm::new(N_P, hold), &e, &[0.35, 3.2e-3, 7.5e-3, 0.4164]);
        time(&format!("spm {hold}"), &PmsmSpm::new(N_P, hold), &e, &[0.35, 5e-3, 0.4164]);
    }
}
