//! SPM model: exactness of the sampled-data step, sensitivities, recovery of known parameters.

use crate::common::{Rng, Signals, exciting_signals, experiment, pmsm_options, sim, simulate_into};
use approx::relative_eq;
use greybox::Experiment;
use greybox::model::{GreyBoxModel, Prepared};
use greybox::pmsm::{HoldChoice, PmsmFitOptions, PmsmSpm, VoltageHold, fit_pmsm};
use greybox::simulate::{SimOptions, visit_sensitivities};
use nalgebra::Complex;
use proptest::prelude::*;

type C = Complex<f64>;

#[allow(clippy::too_many_arguments)]
/// Fine RK4 of `L di/dt = u(s) − (R + jω_e L) i − j √(2/3) K_e ω_m` over one period.
fn rk4_period(
    i0: C,
    u_mean: C,
    w_m: f64,
    n_p: f64,
    th: [f64; 3],
    h: f64,
    hold: VoltageHold,
    steps: usize,
) -> C {
    let [r, l, k_e] = th;
    let w_e = n_p * w_m;
    let phi = w_e * h;
    let u0 = match hold {
        VoltageHold::Dq => u_mean,
        // period mean of u0 e^{−jω s} is u_mean
        _ if phi == 0.0 => u_mean,
        _ => u_mean * C::new(0.0, phi) / (C::new(1.0, 0.0) - C::new(0.0, -phi).exp()),
    };
    let u = |s: f64| match hold {
        VoltageHold::Dq => u0,
        _ => u0 * C::new(0.0, -w_e * s).exp(),
    };
    let z = C::new(r, w_e * l);
    let emf = C::new(0.0, (2.0f64 / 3.0).sqrt() * k_e * w_m);
    let f = |s: f64, i: C| (u(s) - z * i - emf) / l;
    let dt = h / steps as f64;
    let mut i = i0;
    for n in 0..steps {
        let s = n as f64 * dt;
        let k1 = f(s, i);
        let k2 = f(s + dt / 2.0, i + k1 * (dt / 2.0));
        let k3 = f(s + dt / 2.0, i + k2 * (dt / 2.0));
        let k4 = f(s + dt, i + k3 * dt);
        i += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt / 6.0);
    }
    i
}

fn two_sample_experiment(u: C, w0: f64, w1: f64, h: f64) -> Experiment {
    let n = 16;
    let mut s = Signals {
        u_d: vec![u.re; n],
        u_q: vec![u.im; n],
        i_d: vec![0.0; n],
        i_q: vec![0.0; n],
        ..Default::default()
    };
    s.w_m = vec![w1; n];
    s.w_m[0] = w0;
    experiment("one-step", h, s)
}

#[test]
fn exact_step_matches_fine_rk4() {
    let th = [0.9, 4.5e-3, 0.5389];
    let h = 1e-4;
    let mut worst: f64 = 0.0;
    for hold in [VoltageHold::Dq, VoltageHold::Stator] {
        for &(w0, w1) in &[(0.0, 0.0), (280.0, 281.0), (-150.0, -149.0), (1000.0, 1000.0)] {
            let u = C::new(-37.0, 152.0);
            let e = two_sample_experiment(u, w0, w1, h);
            let m = PmsmSpm::new(4, hold);
            let inputs = m.prepare(&e).unwrap();
            let c = m.coefficients(&th, &inputs).unwrap();
            let x = [3.2, -7.5];
            let mut xn = [0.0; 2];
            m.step(&c, &inputs, 0, &x, &mut xn);
            let reference = rk4_period(C::new(x[0], x[1]), u, 0.5 * (w0 + w1), 4.0, th, h, hold, 4000);
            let err = (C::new(xn[0], xn[1]) - reference).norm() / reference.norm();
            worst = worst.max(err);
            assert!(err < 1e-9, "{hold:?} w = {w0}..{w1}: relative error {err:e}");
        }
    }
    eprintln!("SPM step vs RK4: worst relative error {worst:e}");
}

#[test]
fn holds_differ_at_second_order_in_phi() {
    // Guards against a hold silently ignored: at φ = 0.11 rad the two steps differ.
    let th = [0.9, 4.5e-3, 0.5389];
    let e = two_sample_experiment(C::new(10.0, 150.0), 275.0, 275.0, 1e-4);
    let step = |hold| {
        let m = PmsmSpm::new(4, hold);
        let inputs = m.prepare(&e).unwrap();
        let c = m.coefficients(&th, &inputs).unwrap();
        let mut xn = [0.0; 2];
        m.step(&c, &inputs, 0, &[1.0, 2.0], &mut xn);
        C::new(xn[0], xn[1])
    };
    let d = (step(VoltageHold::Dq) - step(VoltageHold::Stator)).norm();
    assert!(d > 1e-4, "holds differ by only {d:e} A");
}

/// Analytic output sensitivities over a trajectory against central differences of the
/// whole simulation. The error of each entry is measured relative to the RMS of its
/// parameter's column (entries that pass through zero have no relative error of their own).
#[test]
fn sensitivities_match_central_differences() {
    let th = [0.9, 4.5e-3, 0.5389];
    let h = 1e-4;
    let mut rng = Rng(7);
    for hold in [VoltageHold::Dq, VoltageHold::Stator] {
        let m = PmsmSpm::new(4, hold);
        // the analytic path, not finite differences of the step
        assert!(m.sensitivities().is_some(), "the SPM model offers analytic sensitivities");
        let e = simulate_into(&m, &th, h, exciting_signals(600, h, 250.0, 60.0, th[2], &mut rng));
        let prep = Prepared::new(&m, &e).unwrap();
        let mut analytic = vec![0.0; 600 * 2 * 3];
        let opts = SimOptions { fd_scale: Some(&[1.0; 3]), ..Default::default() };
        visit_sensitivities(&m, &prep, &th, &opts, |k, _, dy, _| {
            analytic[k * 6..(k + 1) * 6].copy_from_slice(dy);
        })
        .unwrap();
        let mut worst: f64 = 0.0;
        for j in 0..3 {
            let d = 1e-6 * th[j];
            let (mut tp, mut tm) = (th, th);
            tp[j] += d;
            tm[j] -= d;
            let yp = sim(&m, &prep, &tp).unwrap();
            let ym = sim(&m, &prep, &tm).unwrap();
            let col_norm = (0..600 * 2).map(|r| ((yp[r] - ym[r]) / (2.0 * d)).powi(2)).sum::<f64>().sqrt();
            for k in 0..600 {
                for i in 0..2 {
                    let fd = (yp[k * 2 + i] - ym[k * 2 + i]) / (2.0 * d);
                    let an = analytic[k * 6 + i * 3 + j];
                    let err = (fd - an).abs() / col_norm * (600.0f64 * 2.0).sqrt();
                    worst = worst.max(err);
                }
            }
        }
        eprintln!("{hold:?}: worst sensitivity error relative to the column RMS {worst:e}");
        assert!(worst < 1e-6, "{hold:?}: {worst:e}");
    }
}

#[test]
fn invalid_parameters_are_named() {
    let m = PmsmSpm::new(2, VoltageHold::Stator);
    let e = two_sample_experiment(C::new(1.0, 1.0), 1.0, 1.0, 1e-4);
    let inputs = m.prepare(&e).unwrap();
    for (th, name) in [([0.0, 1e-3, 0.1], "r_s"), ([1.0, -1e-3, 0.1], "l_s"), ([1.0, 1e-3, f64::NAN], "k_e")]
    {
        let err = m.coefficients(&th, &inputs).unwrap_err().to_string();
        assert!(err.contains(name), "{err}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]
    /// Random motors and random exciting inputs, simulated by the model itself, are
    /// recovered to 1e-6 from the least-squares start.
    #[test]
    fn recovers_random_spm(r_s in 0.05f64..5.0, l_s in 3e-4f64..2e-2, k_e in 0.05f64..2.0,
                           n_p in 1u32..8, seed in 1u64..u64::MAX, stator in any::<bool>()) {
        let hold = if stator { VoltageHold::Stator } else { VoltageHold::Dq };
        let h = 1e-4;
        let mut rng = Rng(seed);
        let th = [r_s, l_s, k_e];
        // Keep ω_e h below ~0.3 rad and the voltage comparable to the back-EMF.
        let w_max = (0.25 / (n_p as f64 * h)).min(300.0);
        let m = PmsmSpm::new(n_p, hold);
        let e = simulate_into(&m, &th, h, exciting_signals(4000, h, w_max, 30.0 + 50.0 * r_s, k_e, &mut rng));
        let opts = PmsmFitOptions { hold: if stator { HoldChoice::Stator } else { HoldChoice::Dq }, ..pmsm_options(n_p) };
        let fit = fit_pmsm(&[e], &opts).unwrap();
        prop_assert!(fit.solver.success, "{}", fit.solver.termination);
        for (name, truth) in [("r_s", r_s), ("l_s", l_s), ("k_e", k_e)] {
            let est = fit.parameter(name).unwrap().value;
            prop_assert!(relative_eq!(est, truth, max_relative = 1e-6), "{name}: {est} vs {truth}");
        }
    }
}
