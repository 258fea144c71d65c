//! Robust fitting: gross outliers on 1 % of the current samples pull the quadratic fit
//! off; the Huber fit stays within 0.1 % of the truth.

use crate::common::{Rng, Signals, exciting_signals, experiment, pmsm_options, rel, simulate_into};
use greybox::Experiment;
use greybox::estimate::PemOptions;
use greybox::pmsm::{DqView, HoldChoice, PmsmFitOptions, PmsmSpm, VoltageHold, fit_pmsm};

const N_P: u32 = 4;

const THETA: [f64; 3] = [0.9, 4.5e-3, 0.539];
const NAMES: [&str; 3] = ["r_s", "l_s", "k_e"];

/// A simulated record with white noise σ = 0.02 A and, on 1 % of the samples (chosen at
/// random), a gross error of +(5..20) A on i_d or i_q: one-signed glitches, as a current
/// sensor or an ADC read during switching produces, which bias a quadratic fit.
fn record_with_outliers(seed: u64) -> Experiment {
    let h = 1e-4;
    let mut rng = Rng(seed);
    let clean = simulate_into(
        &PmsmSpm::new(N_P, VoltageHold::Stator),
        &THETA,
        h,
        exciting_signals(6000, h, 250.0, 60.0, THETA[2], &mut rng),
    );
    let mut s: Signals = DqView::try_new(&clean).expect("PMSM channels").to_signals();
    let mut outliers = 0;
    for k in 0..s.i_d.len() {
        s.i_d[k] += 0.02 * rng.normal();
        s.i_q[k] += 0.02 * rng.normal();
        if k > 0 && rng.uniform() < 0.01 {
            let spike = 5.0 + 15.0 * rng.uniform();
            if rng.uniform() < 0.5 {
                s.i_d[k] += spike;
            } else {
                s.i_q[k] += spike;
            }
            outliers += 1;
        }
    }
    assert!(outliers > 30, "only {outliers} outliers");
    experiment("outliers", h, s)
}

#[test]
fn huber_fit_resists_one_percent_gross_outliers() {
    for seed in [11, 12, 13] {
        let e = record_with_outliers(seed);
        let quadratic = fit_pmsm(
            std::slice::from_ref(&e),
            &PmsmFitOptions { hold: HoldChoice::Stator, ..pmsm_options(N_P) },
        )
        .unwrap();
        let pem = PemOptions { huber: Some(1.345), ..Default::default() };
        let huber =
            fit_pmsm(&[e], &PmsmFitOptions { hold: HoldChoice::Stator, pem, ..pmsm_options(N_P) }).unwrap();
        assert!(huber.solver.success, "{}", huber.solver.termination);
        let worst = |f: &greybox::estimate::FitResult| {
            NAMES.iter().zip(THETA).map(|(n, t)| rel(f.parameter(n).unwrap().value, t)).fold(0.0, f64::max)
        };
        let (wq, wh) = (worst(&quadratic), worst(&huber));
        eprintln!("seed {seed}: worst relative error quadratic {wq:.3e}, Huber {wh:.3e}");
        assert!(wh < 1e-3, "seed {seed}: Huber fit off by {wh:e}");
        assert!(
            wq > 1e-3,
            "seed {seed}: the quadratic fit is within 0.1 % ({wq:e}): the test does not discriminate"
        );
        for (n, t) in NAMES.iter().zip(THETA) {
            let p = huber.parameter(n).unwrap();
            assert!(((p.value - t) / p.std_error).abs() < 4.0, "{n}: {} ± {} vs {t}", p.value, p.std_error);
        }
    }
}

#[test]
fn huber_fit_equals_quadratic_fit_without_outliers() {
    // With clean Gaussian noise almost every residual lies below δ = 1.345 σ̂, and the
    // estimates agree within a fraction of their standard error.
    let h = 1e-4;
    let mut rng = Rng(5);
    let clean = simulate_into(
        &PmsmSpm::new(N_P, VoltageHold::Stator),
        &THETA,
        h,
        exciting_signals(4000, h, 250.0, 60.0, THETA[2], &mut rng),
    );
    let mut s = DqView::try_new(&clean).expect("PMSM channels").to_signals();
    for k in 0..s.i_d.len() {
        s.i_d[k] += 0.02 * rng.normal();
        s.i_q[k] += 0.02 * rng.normal();
    }
    let e = experiment("clean", h, s);
    let q =
        fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions { hold: HoldChoice::Stator, ..pmsm_options(N_P) })
            .unwrap();
    let pem = PemOptions { huber: Some(1.345), ..Default::default() };
    let hb = fit_pmsm(&[e], &PmsmFitOptions { hold: HoldChoice::Stator, pem, ..pmsm_options(N_P) }).unwrap();
    for n in NAMES {
        let (a, b) = (q.parameter(n).unwrap(), hb.parameter(n).unwrap());
        assert!(((a.value - b.value) / a.std_error).abs() < 0.5, "{n}: {} vs {}", a.value, b.value);
        // Huber's efficiency at c = 1.345 is 95 %: standard errors ≈ 1/√0.95 larger.
        let ratio = b.std_error / a.std_error;
        assert!((0.95..1.15).contains(&ratio), "{n}: se ratio {ratio}");
    }
}
