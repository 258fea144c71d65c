//! The firmware core's observers on a surface-magnet machine simulated by its own exact
//! step (so the observers' model is right): from wrong starts both reach the truth, in
//! `f64` and in `f32`; bad samples and settings are refused without a change of state.

mod common;

use greybox_observer::{Adaptation, Fault, Field, Kalman, Mras, Noise, Real, Sample, Settings, Spm};

const N_P: u32 = 4;
const L_S: f64 = 4.5e-3;
const R_S: f64 = 0.9;
const K_E: f64 = 0.54;
const H: f64 = 1e-4;

/// `n` samples of the machine driven open loop (`common::open_loop`; stator hold).
fn simulate(n: usize) -> Vec<Sample<f64>> {
    common::open_loop(&Spm::new(&Settings::new(N_P, L_S, H)), n, H, K_E, R_S, -3.0)
}

fn cast<T: Real>(s: &Sample<f64>) -> Sample<T> {
    Sample { i_d: T::c(s.i_d), i_q: T::c(s.i_q), u_d: T::c(s.u_d), u_q: T::c(s.u_q), w_m: T::c(s.w_m) }
}

fn settings<T: Real>() -> Settings<T> {
    let mut s = Settings::new(N_P, T::c(L_S), T::c(H));
    s.adaptation = Adaptation::Normalised;
    (s.k_e0, s.r_s0) = (T::c(0.8 * K_E), T::c(1.5 * R_S));
    s
}

/// The MRAS and the filter over `samples` in precision `T`: their last estimates as f64
/// `(k_e, r_s)` and the filter's standard errors.
fn run<T: Real>(samples: &[Sample<f64>]) -> ((f64, f64), (f64, f64, f64, f64)) {
    let s = settings::<T>();
    let mut mras = Mras::spm(s).unwrap();
    let mut ekf = Kalman::spm(s, Noise::for_machine(T::c(1e-3), s.r_s0, s.k_e0)).unwrap();
    let (mut m, mut e) = (mras.output(), mras.output());
    for x in samples {
        let x = cast::<T>(x);
        m = mras.update(&x).unwrap();
        e = ekf.update(&x).unwrap();
    }
    let f = |v: T| v.to_f64().unwrap();
    ((f(m.k_e), f(m.r_s)), (f(e.k_e), f(e.r_s), f(e.k_e_se), f(e.r_s_se)))
}

#[test]
fn both_observers_reach_the_truth_in_f64_and_f32() {
    let samples = simulate(60_000);
    assert!(samples.iter().filter(|s| s.i_d.abs() > 0.5).count() > 10_000, "the R_s law must be active");
    for (precision, ((mk, mr), (ek, er, ek_se, er_se)), tol) in
        [("f64", run::<f64>(&samples), 1e-9), ("f32", run::<f32>(&samples), 1e-4)]
    {
        assert!((mk / K_E - 1.0).abs() < tol, "{precision} MRAS K_e {mk}");
        assert!((mr / R_S - 1.0).abs() < 10.0 * tol, "{precision} MRAS R_s {mr}");
        assert!((ek / K_E - 1.0).abs() < tol, "{precision} EKF K_e {ek}");
        assert!((er / R_S - 1.0).abs() < 10.0 * tol, "{precision} EKF R_s {er}");
        // Noise-free: the truth within the filter's 95 % band, the band not wider than 1 %.
        assert!((ek - K_E).abs() < 1.96 * ek_se + 1e-6 && ek_se < 0.01 * K_E, "{precision} K_e se {ek_se}");
        assert!((er - R_S).abs() < 1.96 * er_se + 1e-5 && er_se < 0.01 * R_S, "{precision} R_s se {er_se}");
    }
}

#[test]
fn a_bad_sample_is_refused_and_changes_nothing() {
    let samples = simulate(2_000);
    let s = settings::<f64>();
    let mut mras = Mras::spm(s).unwrap();
    let mut ekf = Kalman::spm(s, Noise::for_machine(1e-3, s.r_s0, s.k_e0)).unwrap();
    let (mut m2, mut e2) = (mras, ekf);
    for (k, x) in samples.iter().enumerate() {
        if k == 1000 {
            let bad = Sample { w_m: f64::NAN, ..*x };
            assert!(matches!(mras.update(&bad), Err(Fault::NonFinite { channel: 4, sample: 1000 })));
            assert!(matches!(ekf.update(&bad), Err(Fault::NonFinite { channel: 4, sample: 1000 })));
            let inf = Sample { i_q: f64::INFINITY, ..*x };
            assert!(matches!(ekf.update(&inf), Err(Fault::NonFinite { channel: 1, .. })));
        }
        assert_eq!(mras.update(x).unwrap(), m2.update(x).unwrap());
        assert_eq!(ekf.update(x).unwrap(), e2.update(x).unwrap());
    }
}

#[test]
fn settings_out_of_range_are_named() {
    let good = settings::<f64>();
    type Change = fn(&mut Settings<f64>);
    let cases: [(Change, Field); 6] = [
        (|s| s.n_p = 0, Field::NP),
        (|s| s.l_s = 0.0, Field::LS),
        (|s| s.h = f64::NAN, Field::H),
        (|s| s.tau_ke = 50.0 * s.h, Field::TauKe),
        (|s| s.gamma_rs = 1.0, Field::GammaRs),
        (|s| s.k_e0 = f64::INFINITY, Field::KE0),
    ];
    for (change, field) in cases {
        let mut s = good;
        change(&mut s);
        assert_eq!(Mras::spm(s).err(), Some(field));
        assert_eq!(Kalman::spm(s, Noise::for_machine(1e-3, 1.0, 0.5)).err(), Some(field));
    }
    let mut n = Noise::for_machine(1e-3, 1.0, 0.5);
    n.sigma_i = 0.0;
    assert_eq!(Kalman::spm(good, n).err(), Some(Field::SigmaI));
    assert_eq!(Field::SigmaI.name(), "sigma_i");
}
