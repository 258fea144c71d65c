//! Monte-Carlo study of the reported uncertainty (the long run behind `tests/it/coverage.rs`):
//! `cargo run --release --example monte_carlo [-- REALISATIONS]` (default 2000).
//!
//! One simulated SPM record (R_s 0.9 Ω, L_s 4.5 mH, K_e 0.539 V s/rad, n_p 4, h 100 µs,
//! 2500 samples of random voltage steps over a reversing speed sweep to 250 rad/s) gets
//! white Gaussian noise σ = 0.1 A on i_d and i_q, a new seed per realisation, and is fitted
//! from its least-squares start with the stator hold. Per parameter the table shows the
//! bias, the spread of the estimates against the mean reported standard error, and how
//! often the reported 95 % interval contains the truth (binomial ±1.96 σ band alongside),
//! for four treatments of the initial state i[0] that the simulation starts from:
//!
//! - `x0 estimated`: noise on every sample, plain `fit_pmsm` (estimates the initial state);
//! - `noisy i[0]`: noise on every sample, the first sample taken as the exact initial state;
//! - `exact i[0]`: noise from sample 1 on (a log starting at standstill, zero current),
//!   first sample taken as exact;
//! - `transient out`: noise on every sample, the first 500 residuals (10 L/R) weighted 0,
//!   first sample taken as exact.

#[path = "../tests/it/common/mod.rs"]
mod common;

use common::{Rng, exciting_signals, simulate_into};
use greybox::Experiment;
use greybox::estimate::CustomWeighting;
use greybox::estimate::{FitResult, PemOptions, fit_with_weighting};
use greybox::pmsm::{
    DqView, HoldChoice, MotorKind, PmsmFitOptions, PmsmSpm, VoltageHold, fit_pmsm, least_squares,
};
use rayon::prelude::*;

const THETA: [f64; 3] = [0.9, 4.5e-3, 0.539];
const NAMES: [&str; 3] = ["r_s", "l_s", "k_e"];
const N_P: u32 = 4;
const N: usize = 2500;
const H: f64 = 1e-4;
const SIGMA: f64 = 0.1;
const TRANSIENT: usize = 500;

/// Estimate, standard error and 95 % interval of one parameter.
type Row = (f64, f64, [f64; 2]);

#[derive(Clone, Copy, Debug)]
enum Scenario {
    EstimatedStart,
    NoisyStart,
    ExactStart,
    TransientOut,
}

impl Scenario {
    fn label(self) -> &'static str {
        match self {
            Self::EstimatedStart => "x0 estimated",
            Self::NoisyStart => "noisy i[0]",
            Self::ExactStart => "exact i[0]",
            Self::TransientOut => "transient out",
        }
    }
}

fn noisy(clean: &Experiment, seed: u64, first: usize) -> Experiment {
    let mut rng = Rng(seed);
    let mut s = DqView::try_new(clean).expect("a PMSM record").to_signals();
    for v in s.i_d[first..].iter_mut().chain(s.i_q[first..].iter_mut()) {
        *v += SIGMA * rng.normal();
    }
    s.into_experiment("noisy", clean.h()).expect("valid signals")
}

fn fit_one(clean: &Experiment, scenario: Scenario, r: u64) -> greybox::Result<FitResult> {
    let seed = 0x9e37_79b9_7f4a_7c15u64.wrapping_mul(r + 1);
    let fixed = PemOptions { estimate_x0: false, ..Default::default() };
    let estimated = PmsmFitOptions { hold: HoldChoice::Stator, ..PmsmFitOptions::new(N_P) };
    let opts = PmsmFitOptions { pem: fixed.clone(), ..estimated.clone() };
    // `fit_pmsm` wraps the generic report with what only a motor fit has; keep the report.
    let pmsm = |e: Experiment, o: &PmsmFitOptions| fit_pmsm(&[e], o).map(|f| f.report);
    match scenario {
        Scenario::EstimatedStart => pmsm(noisy(clean, seed, 0), &estimated),
        Scenario::NoisyStart => pmsm(noisy(clean, seed, 0), &opts),
        Scenario::ExactStart => pmsm(noisy(clean, seed, 1), &opts),
        Scenario::TransientOut => {
            let e = noisy(clean, seed, 0);
            let start = least_squares(std::slice::from_ref(&e), N_P, MotorKind::Spm)?.theta;
            let skip = CustomWeighting::new("skip transient", |_, k| if k < TRANSIENT { 0.0 } else { 1.0 });
            fit_with_weighting(&PmsmSpm::new(N_P, VoltageHold::Stator), &[e], &start, &fixed, &skip)
        }
    }
}

fn main() -> greybox::Result<()> {
    let realisations: u64 = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(2000);
    let mut rng = Rng(0x5eed_c0de);
    let signals = exciting_signals(N, H, 250.0, 60.0, THETA[2], &mut rng);
    let clean = simulate_into(&PmsmSpm::new(N_P, VoltageHold::Stator), &THETA, H, signals);
    let band = 1.96 * (0.95f64 * 0.05 / realisations as f64).sqrt() * 100.0;
    println!(
        "{realisations} realisations, N = {N}, σ = {SIGMA} A on i_d, i_q; coverage expected 95 ± {band:.1} %"
    );
    println!(
        "{:<14} {:<5} {:>11} {:>11} {:>11} {:>11} {:>8} {:>10} {:>8}",
        "i[0]", "param", "truth", "bias/truth", "sd(θ̂)", "mean se", "sd/se", "coverage", "failed"
    );
    for scenario in
        [Scenario::EstimatedStart, Scenario::NoisyStart, Scenario::ExactStart, Scenario::TransientOut]
    {
        let fits: Vec<Option<[Row; 3]>> = (0..realisations)
            .into_par_iter()
            .map(|r| {
                let fit = fit_one(&clean, scenario, r).ok().filter(|f| f.solver.success)?;
                let row = |n: &str| fit.parameter(n).map(|p| (p.value, p.std_error, p.ci95));
                Some([row(NAMES[0])?, row(NAMES[1])?, row(NAMES[2])?])
            })
            .collect();
        let ok: Vec<_> = fits.iter().flatten().collect();
        let failed = fits.len() - ok.len();
        let n = ok.len() as f64;
        for (j, name) in NAMES.iter().enumerate() {
            let mean = ok.iter().map(|f| f[j].0).sum::<f64>() / n;
            let sd = (ok.iter().map(|f| (f[j].0 - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let se = ok.iter().map(|f| f[j].1).sum::<f64>() / n;
            let hits = ok.iter().filter(|f| f[j].2[0] <= THETA[j] && THETA[j] <= f[j].2[1]).count();
            println!(
                "{:<14} {:<5} {:>11.4e} {:>+11.2e} {:>11.3e} {:>11.3e} {:>8.3} {:>9.1} % {:>8}",
                scenario.label(),
                name,
                THETA[j],
                (mean - THETA[j]) / THETA[j],
                sd,
                se,
                sd / se,
                100.0 * hits as f64 / n,
                failed
            );
        }
    }
    Ok(())
}
