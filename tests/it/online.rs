//! The MRAS observer (thesis 5.1, MODEL.md §7): exactness of its discrete observer,
//! convergence to known parameters, tracking, stability at large gain × sample time, errors.

use crate::common::{Rng, Signals, exciting_signals, experiment, rel, require_shared, simulate_into};
use approx::relative_eq;
use greybox::Error;
use greybox::model::Prepared;
use greybox::online::{Adaptation, InjectionSchedule, Mras, MrasConfig, Sample, track};
use greybox::pmsm::{DqView, PmsmIpm, PmsmSpm, VoltageHold};
use greybox::simulate::{SimOptions, simulate};

/// The servo of the development logs: R_s [Ω], L_s [H], K_e [V s/rad], n_p.
const R_S: f64 = 0.9;
const L_S: f64 = 4.5e-3;
const K_E: f64 = 0.538_887_743_412_299_2;
const N_P: u32 = 4;

/// A synthetic log of `n` samples at `h` from the crate's exact SPM model at
/// `(R_S, L_S, k_e)`: random voltage steps (d current nearly always present), speed
/// sweeping ±`w_max` [rad/s].
fn plant(n: usize, h: f64, w_max: f64, k_e: f64, hold: VoltageHold, seed: u64) -> greybox::Experiment {
    let s = exciting_signals(n, h, w_max, 10.0, k_e, &mut Rng(seed));
    simulate_into(&PmsmSpm::new(N_P, hold), &[R_S, L_S, k_e], h, s)
}

fn config(h: f64, hold: VoltageHold) -> MrasConfig {
    MrasConfig { n_p: N_P, l_s: L_S, h, k_e0: 0.8 * K_E, r_s0: 0.8 * R_S, hold, ..Default::default() }
}

/// Runs the observer over a log; returns the per-sample estimates.
fn run(e: &greybox::Experiment, cfg: &MrasConfig) -> greybox::online::Trajectory {
    track(e, cfg).expect("track")
}

/// Largest relative error of K̂_e and R̂_s over the last `tail` points of a trajectory.
fn tail_errors(tr: &greybox::online::Trajectory, tail: usize, k_e: f64, r_s: f64) -> (f64, f64) {
    let n = tr.t.len();
    let k = tr.k_e[n - tail..].iter().map(|&x| rel(x, k_e)).fold(0.0, f64::max);
    let r = tr.r_s[n - tail..].iter().map(|&x| rel(x, r_s)).fold(0.0, f64::max);
    (k, r)
}

/// The largest observer error `|e|` [A] over a log (each period's voltage, interval-mean
/// speed) and the largest current magnitude.
fn observer_error(m: &mut Mras, v: &DqView<'_>) -> (f64, f64) {
    let (u_d, u_q) = v.terminal_voltage().unwrap();
    let (w, mut worst, mut peak) = (v.w_m(), 0.0f64, 0.0f64);
    for k in 0..v.len() - 1 {
        let s = Sample {
            i_d: v.i_d()[k],
            i_q: v.i_q()[k],
            u_d: u_d[k],
            u_q: u_q[k],
            w_m: 0.5 * (w[k] + w[k + 1]),
        };
        let est = m.update(&s).unwrap();
        worst = worst.max(est.e_d.hypot(est.e_q));
        peak = peak.max(s.i_d.hypot(s.i_q));
    }
    (worst, peak)
}

#[test]
fn observer_without_adaptation_reproduces_the_exact_spm_simulation() {
    for hold in [VoltageHold::Stator, VoltageHold::Dq] {
        let h = 1e-4;
        let e = plant(20_000, h, 250.0, K_E, hold, 7);
        let v = DqView::try_new(&e).unwrap();
        let cfg = MrasConfig { k_e0: K_E, r_s0: R_S, gamma_ke: 0.0, gamma_rs: 0.0, ..config(h, hold) };
        let mut m = Mras::try_new(cfg).unwrap();
        let (worst, peak) = observer_error(&mut m, &v);
        eprintln!("exactness, {hold} hold: max |e| = {worst:.2e} A (peak current {peak:.1} A)");
        assert!(worst < 1e-12 * peak.max(1.0), "{hold}: {worst:e}");
    }
}

#[test]
fn lyapunov_and_relay_converge_from_80_percent() {
    let h = 1e-4;
    let e = plant(60_000, h, 200.0, K_E, VoltageHold::Stator, 11);
    for (adaptation, gamma_ke) in [(Adaptation::Lyapunov, 0.001), (Adaptation::Relay, 0.1)] {
        let cfg = MrasConfig { adaptation, gamma_ke, ..config(h, VoltageHold::Stator) };
        let tr = run(&e, &cfg);
        let (ek, er) = tail_errors(&tr, 10_000, K_E, R_S);
        eprintln!("{adaptation:?}: over the last 1 s, max rel. error K_e {ek:.2e}, R_s {er:.2e}");
        assert!(ek < 5e-3, "{adaptation:?}: K_e {ek:e}");
        assert!(er < 2e-2, "{adaptation:?}: R_s {er:e}");
    }
}

#[test]
fn tracks_a_step_in_k_e() {
    // The plant's K_e drops by 5 % at the middle of the record (e.g. a hot magnet); the
    // segments join with the state continuous.
    let (h, n) = (1e-4, 40_000);
    let s = exciting_signals(n, h, 200.0, 10.0, K_E, &mut Rng(5));
    let model = PmsmSpm::new(N_P, VoltageHold::Stator);
    let half = n / 2;
    let seg = |range: std::ops::Range<usize>| Signals {
        u_d: s.u_d[range.clone()].to_vec(),
        u_q: s.u_q[range.clone()].to_vec(),
        i_d: vec![0.0; range.len()],
        i_q: vec![0.0; range.len()],
        w_m: s.w_m[range].to_vec(),
        ..Default::default()
    };
    let first = simulate_into(&model, &[R_S, L_S, K_E], h, seg(0..half + 1));
    let (id1, iq1) = (first.channel("id").unwrap(), first.channel("iq").unwrap());
    let x0 = [id1[half], iq1[half]];
    let second_in = experiment("second", h, seg(half..n));
    let prep = Prepared::new(&model, &second_in).unwrap();
    let k_e2 = 0.95 * K_E;
    let y = simulate(&model, &prep, &[R_S, L_S, k_e2], &SimOptions { x0: Some(&x0), ..Default::default() })
        .unwrap();
    let mut all = s.clone();
    all.i_d = id1[..half].iter().copied().chain(y.iter().step_by(2).copied()).collect();
    all.i_q = iq1[..half].iter().copied().chain(y.iter().skip(1).step_by(2).copied()).collect();
    let e = experiment("k_e step", h, all);
    let tr = run(&e, &config(h, VoltageHold::Stator));
    let before = rel(tr.k_e[half - 1], K_E);
    let (after, r_after) = tail_errors(&tr, 5_000, k_e2, R_S);
    // Time after the step until K̂_e stays within 0.5 % of the new value.
    let settle = (half..tr.t.len()).rev().find(|&k| rel(tr.k_e[k], k_e2) > 5e-3).map_or(0, |k| k + 1 - half);
    eprintln!(
        "K_e step: before {before:.2e}, last 0.5 s {after:.2e} (R_s {r_after:.2e}), settles to 0.5 % in {:.3} s",
        settle as f64 * h
    );
    assert!(relative_eq!(tr.k_e[half - 1], K_E, max_relative = 5e-3) && after < 5e-3, "{before:e} {after:e}");
}

/// The thesis' K_e law by explicit Euler, `K̂ += γ h Dᵀ e[k]`, around the same exact
/// observer step (dq hold, `R̂_s` fixed at the truth): the update the library's implicit
/// form replaces. Returns the largest |K̂_e| reached (infinite once it overflows).
fn explicit_euler_k_e(e: &greybox::Experiment, gamma_ke: f64, f: f64, k_e0: f64) -> f64 {
    use nalgebra::Complex;
    let v = DqView::try_new(e).unwrap();
    let (h, w) = (e.h(), v.w_m());
    let kappa = 1.0 - (-f * h).exp();
    let (mut i_hat, mut k_e, mut worst) = (Complex::new(v.i_d()[0], v.i_q()[0]), k_e0, 0.0f64);
    for k in 0..v.len() - 1 {
        let i = Complex::new(v.i_d()[k], v.i_q()[k]);
        let err = i - i_hat;
        let w_m = 0.5 * (w[k] + w[k + 1]);
        let emf = (2.0f64 / 3.0).sqrt() * w_m;
        k_e += gamma_ke * h * (-emf / L_S) * err.im;
        worst = worst.max(k_e.abs());
        if !worst.is_finite() || worst > 1e6 {
            return f64::INFINITY;
        }
        let z = Complex::new(R_S, f64::from(N_P) * w_m * L_S);
        let a = (-z * h / L_S).exp();
        let b = (Complex::new(1.0, 0.0) - a) / z;
        let u = Complex::new(v.terminal_voltage().unwrap().0[k], v.terminal_voltage().unwrap().1[k]);
        i_hat = a * (i_hat + err * kappa) + b * (u - Complex::new(0.0, emf * k_e));
    }
    worst
}

#[test]
fn stable_where_an_explicit_update_diverges() {
    // h = 1 ms and γ_Ke = 0.01: the explicit update's self-coupling 1 − g has
    // g ≈ γ_Ke emf² h²/L_s² ≈ 13 at 200 rad/s, far beyond its bound g < 2.
    let (h, w_max, gamma_ke) = (1e-3, 200.0, 0.01);
    let emf = (2.0f64 / 3.0).sqrt() * w_max;
    let g = gamma_ke * emf * emf * h * h / (L_S * L_S);
    assert!(g > 2.0, "{g}");
    for hold in [VoltageHold::Dq, VoltageHold::Stator] {
        let e = plant(10_000, h, w_max, K_E, hold, 3);
        let cfg = MrasConfig { gamma_ke, gamma_rs: -1000.0, ..config(h, hold) };
        let tr = run(&e, &cfg);
        let bounded = tr.k_e.iter().all(|k| k.abs() < 10.0 * K_E) && tr.r_s.iter().all(|r| *r < 10.0 * R_S);
        let (ek, er) = tail_errors(&tr, 1_000, K_E, R_S);
        eprintln!(
            "h = 1 ms, g = {g:.1}, {hold} hold: bounded {bounded}, last 1 s max rel. error K_e {ek:.2e}, R_s {er:.2e}"
        );
        assert!(bounded);
        assert!(ek < 5e-3 && er < 2e-2, "{ek:e} {er:e}");
    }
    // The same gain by explicit Euler blows up; a gain 100 times smaller (g ≈ 0.13) does not.
    let e = plant(10_000, h, w_max, K_E, VoltageHold::Dq, 3);
    let (big, small) = (
        explicit_euler_k_e(&e, gamma_ke, 100.0, 0.8 * K_E),
        explicit_euler_k_e(&e, gamma_ke / 100.0, 100.0, 0.8 * K_E),
    );
    eprintln!("explicit Euler: max |K_e| {big:.3e} at g = {g:.1}, {small:.3e} at g = {:.2}", g / 100.0);
    assert!(big > 1e6 && small < 2.0 * K_E, "{big:e} {small:e}");
}

#[test]
fn bad_samples_and_settings_are_errors() {
    let mut m = Mras::try_new(config(1e-4, VoltageHold::Stator)).unwrap();
    let ok = Sample { i_d: 1.0, i_q: 2.0, u_d: 3.0, u_q: 40.0, w_m: 50.0 };
    m.update(&ok).unwrap();
    let before = m.output();
    match m.update(&Sample { u_q: f64::NAN, ..ok }) {
        Err(Error::NonFinite { column, row, .. }) => assert_eq!((column.as_str(), row), ("u_q", 1)),
        other => panic!("{other:?}"),
    }
    assert_eq!(m.output(), before);
    assert!(matches!(m.update(&Sample { w_m: f64::INFINITY, ..ok }), Err(Error::NonFinite { .. })));
    // The compute-output / update split: computing changes nothing, a stale output is refused.
    let out = m.compute_output(&Sample { i_q: 2.5, ..ok }).unwrap();
    assert_eq!(m.output(), before);
    m.advance(&out).unwrap();
    assert_eq!(m.output(), out.estimates);
    assert!(matches!(m.advance(&out), Err(Error::InvalidOption { .. })));
    m.update(&ok).unwrap();

    let field = |cfg: MrasConfig| match Mras::try_new(cfg) {
        Err(Error::InvalidOption { option, .. }) => option,
        other => panic!("{other:?}"),
    };
    let good = config(1e-4, VoltageHold::Stator);
    assert_eq!(field(MrasConfig::default()), "n_p");
    assert_eq!(field(MrasConfig { l_s: 0.0, ..good.clone() }), "l_s");
    assert_eq!(field(MrasConfig { h: f64::NAN, ..good.clone() }), "h");
    assert_eq!(field(MrasConfig { f: -1.0, ..good.clone() }), "f");
    assert_eq!(field(MrasConfig { gamma_ke: f64::INFINITY, ..good.clone() }), "gamma_ke");
    assert_eq!(field(MrasConfig { gamma_rs: 10.0, ..good.clone() }), "gamma_rs");
    assert_eq!(field(MrasConfig { r_s0: -0.1, ..good.clone() }), "r_s0");
    assert_eq!(field(MrasConfig { k_e0: f64::NAN, ..good.clone() }), "k_e0");
    assert_eq!(field(MrasConfig { i_d_threshold: -1.0, ..good }), "i_d_threshold");
    let json = serde_json::to_string(&config(1e-4, VoltageHold::Dq)).unwrap();
    let back: MrasConfig = serde_json::from_str(&json).unwrap();
    assert_eq!(back, config(1e-4, VoltageHold::Dq));
}

#[test]
fn injection_schedule() {
    let s = InjectionSchedule::try_new(600.0, 1.0, -4.0).unwrap();
    assert_eq!(s.i_d_reference(0.5), -4.0);
    assert_eq!(s.i_d_reference(1.5), 0.0);
    assert_eq!(s.i_d_reference(600.2), -4.0);
    assert_eq!(s.i_d_reference(-1.0), 0.0);
    assert_eq!(s.i_d_reference(f64::NAN), 0.0);
    let d = InjectionSchedule::default();
    assert_eq!((d.period_s, d.duration_s), (600.0, 1.0));
    for (p, d, a, name) in
        [(0.0, 0.0, 1.0, "period_s"), (10.0, 11.0, 1.0, "duration_s"), (10.0, 1.0, f64::NAN, "i_d_amplitude")]
    {
        match InjectionSchedule::try_new(p, d, a) {
            Err(Error::InvalidOption { option, .. }) => assert_eq!(option, name),
            other => panic!("{other:?}"),
        }
    }
    let cfg = config(1e-4, VoltageHold::Stator);
    assert!(cfg.r_s_adapts(-4.0) && !cfg.r_s_adapts(0.1) && !cfg.r_s_adapts(f64::NAN));
}

#[test]
fn trajectory_decimates_keeping_the_last_point() {
    let e = plant(1_000, 1e-4, 100.0, K_E, VoltageHold::Stator, 1);
    let tr = run(&e, &config(1e-4, VoltageHold::Stator));
    for m in [0, 1, 2, 7, 100, 998, 999, 5000] {
        let d = tr.decimate(m);
        assert!(d.t.len() <= m.max(1), "{m}: {}", d.t.len());
        assert_eq!(d.t.last(), tr.t.last());
        assert_eq!((d.k_e.len(), d.r_s.len()), (d.t.len(), d.t.len()));
    }
    assert_eq!(tr.final_estimate.k_e, *tr.k_e.last().unwrap());
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn servo_log_with_d_injection() {
    require_shared!();
    let (e, truth) = crate::common::load("servo_spm_moves_idinj");
    let cfg = MrasConfig {
        n_p: truth.n_p,
        l_s: truth.l_d,
        k_e0: 0.8 * truth.k_e,
        r_s0: 0.8 * truth.r_s,
        ..Default::default()
    };
    let tr = run(&e, &cfg);
    let n = tr.t.len();
    let (ek, er) = tail_errors(&tr, n / 10, truth.k_e, truth.r_s);
    eprintln!(
        "servo_spm_moves_idinj: final K_e {:.6} (truth {:.6}), R_s {:.4} (truth {}); last 10 % max rel. error K_e {ek:.2e}, R_s {er:.2e}",
        tr.final_estimate.k_e, truth.k_e, tr.final_estimate.r_s, truth.r_s
    );
    assert!(ek < 5e-3, "K_e {ek:e}");
}

proptest::proptest! {
    /// Garbage in: the observer answers with a value or an error, never a panic, and what it
    /// answers is finite.
    #[test]
    fn garbage_never_panics(
        l_s in proptest::num::f64::ANY, h in proptest::num::f64::ANY, f in proptest::num::f64::ANY,
        gamma_ke in proptest::num::f64::ANY, gamma_rs in proptest::num::f64::ANY,
        samples in proptest::collection::vec(proptest::array::uniform5(proptest::num::f64::ANY), 1..20),
    ) {
        let cfg = MrasConfig { n_p: 2, l_s, h, f, gamma_ke, gamma_rs, k_e0: 0.1, r_s0: 0.5, ..Default::default() };
        let good = MrasConfig { gamma_ke: 10.0, ..config(1e-4, VoltageHold::Stator) };
        for cfg in [cfg, good] {
            let Ok(mut m) = Mras::try_new(cfg) else { continue };
            for &[i_d, i_q, u_d, u_q, w_m] in &samples {
                if let Ok(est) = m.update(&Sample { i_d, i_q, u_d, u_q, w_m }) {
                    proptest::prop_assert!(est.k_e.is_finite() && est.r_s.is_finite() && est.r_s >= 0.0);
                }
            }
        }
    }
}

/// The salient machine of motulator's development logs (`ipm_moves_idinj`): R_s [Ω],
/// L_d, L_q [H], K_e [V s/rad], n_p.
const IPM_R_S: f64 = 0.35;
const IPM_L_D: f64 = 3.2e-3;
const IPM_L_Q: f64 = 7.5e-3;
const IPM_K_E: f64 = 0.416_413_256_273_140_3;
const IPM_N_P: u32 = 2;

/// A synthetic log of `n` samples at `h` from the crate's exact IPM model (augmented
/// exponential) at the truth: random voltage steps, speed sweeping ±`w_max` [rad/s].
fn ipm_plant(n: usize, h: f64, w_max: f64, hold: VoltageHold, seed: u64) -> greybox::Experiment {
    let s = exciting_signals(n, h, w_max, 10.0, IPM_K_E, &mut Rng(seed));
    simulate_into(&PmsmIpm::new(IPM_N_P, hold), &[IPM_R_S, IPM_L_D, IPM_L_Q, IPM_K_E], h, s)
}

fn ipm_config(h: f64, hold: VoltageHold) -> MrasConfig {
    MrasConfig {
        n_p: IPM_N_P,
        l_s: IPM_L_D,
        l_q: Some(IPM_L_Q),
        h,
        k_e0: 0.8 * IPM_K_E,
        r_s0: 0.8 * IPM_R_S,
        hold,
        ..Default::default()
    }
}

#[test]
fn salient_observer_without_adaptation_reproduces_the_exact_ipm_simulation() {
    for hold in [VoltageHold::Stator, VoltageHold::Dq] {
        let h = 1e-4;
        let e = ipm_plant(20_000, h, 250.0, hold, 7);
        let v = DqView::try_new(&e).unwrap();
        let cfg =
            MrasConfig { k_e0: IPM_K_E, r_s0: IPM_R_S, gamma_ke: 0.0, gamma_rs: 0.0, ..ipm_config(h, hold) };
        let mut m = Mras::try_new(cfg).unwrap();
        let (worst, peak) = observer_error(&mut m, &v);
        eprintln!("salient exactness, {hold} hold: max |e| = {worst:.2e} A (peak current {peak:.1} A)");
        assert!(worst < 1e-12 * peak.max(1.0), "{hold}: {worst:e}");
    }
}

/// The firmware core's salient step (`greybox_observer::Ipm`, which `greybox track` and the
/// C ABI step with) is `ExactPlant::step_derivatives` (the offline model's) to the bit:
/// the same series, the same start voltage, either hold.
#[test]
fn the_core_salient_step_is_the_exact_plants_to_the_bit() {
    use greybox::pmsm::{C64, ExactPlant, MotorParameters, stator_hold_start};
    use greybox_observer::{Hold, Ipm, Plant, Settings};
    let h = 2e-4;
    let mut rng = Rng(23);
    for (hold, core_hold) in [(VoltageHold::Stator, Hold::Stator), (VoltageHold::Dq, Hold::Dq)] {
        let plant = ExactPlant::new(IPM_N_P, h, true, hold).unwrap();
        let mut s = Settings::new(IPM_N_P, IPM_L_D, h);
        s.hold = core_hold;
        let ipm = Ipm::new(&s, IPM_L_Q).unwrap();
        for _ in 0..300 {
            let mut u = || 2.0 * rng.uniform() - 1.0;
            let (i, u, w_m, k_e, r_s) = (
                [30.0 * u(), 30.0 * u()],
                C64::new(200.0 * u(), 200.0 * u()),
                2000.0 * u(),
                0.5 + 0.1 * u(),
                0.4 + 0.3 * u(),
            );
            let p = MotorParameters {
                r_s,
                l_d: IPM_L_D,
                l_q: IPM_L_Q,
                psi_f: (2.0f64 / 3.0).sqrt() * k_e / f64::from(IPM_N_P),
                n_p: IPM_N_P,
            };
            let u0 = match hold {
                VoltageHold::Stator => stator_hold_start(u, f64::from(IPM_N_P) * w_m * h),
                VoltageHold::Dq => u,
            };
            let want = plant.step_derivatives(&p, i, u0, w_m).unwrap();
            let sample = greybox_observer::Sample { i_d: i[0], i_q: i[1], u_d: u.re, u_q: u.im, w_m };
            let got = ipm.step(C64::new(i[0], i[1]), k_e, r_s, &sample, false).unwrap();
            let bits = |c: C64| [c.re.to_bits(), c.im.to_bits()];
            let pair = |v: [f64; 2]| bits(C64::new(v[0], v[1]));
            assert_eq!(bits(got.next), pair(want.next), "{hold} w_m {w_m}");
            assert_eq!(bits(got.phi_r), pair(want.d_r_s), "{hold} w_m {w_m}");
            assert_eq!(bits(got.phi_k), pair(want.d_k_e), "{hold} w_m {w_m}");
        }
    }
}

#[test]
fn salient_step_derivatives_are_exact() {
    use greybox::pmsm::{C64, ExactPlant, MotorParameters, StepDerivatives};
    let h = 2e-4;
    let params = |r_s: f64, k_e: f64| MotorParameters {
        r_s,
        l_d: IPM_L_D,
        l_q: IPM_L_Q,
        psi_f: (2.0f64 / 3.0).sqrt() * k_e / f64::from(IPM_N_P),
        n_p: IPM_N_P,
    };
    let mut rng = Rng(17);
    let (mut worst_k, mut worst_r) = (0.0f64, 0.0f64);
    for hold in [VoltageHold::Stator, VoltageHold::Dq] {
        let mut plant = ExactPlant::new(IPM_N_P, h, true, hold).unwrap();
        for _ in 0..200 {
            let mut u = || 2.0 * rng.uniform() - 1.0;
            let (i, u0, w_m) = ([30.0 * u(), 30.0 * u()], C64::new(200.0 * u(), 200.0 * u()), 400.0 * u());
            let p = params(IPM_R_S, IPM_K_E);
            let StepDerivatives { next, d_r_s, d_k_e } = plant.step_derivatives(&p, i, u0, w_m).unwrap();
            // The same step as ExactPlant::step.
            let stepped = plant.step(&p, i, u0, w_m).unwrap();
            let scale = 1.0 + next[0].hypot(next[1]);
            assert!((next[0] - stepped[0]).hypot(next[1] - stepped[1]) < 1e-13 * scale);
            // Affine in (i, u, K_e): ∂/∂K_e is the step from zero current and voltage at unit K_e.
            let unit = plant.step(&params(IPM_R_S, 1.0), [0.0; 2], C64::default(), w_m).unwrap();
            let ek = (d_k_e[0] - unit[0]).hypot(d_k_e[1] - unit[1]) / (1e-300 + d_k_e[0].hypot(d_k_e[1]));
            worst_k = worst_k.max(ek);
            // ∂/∂R_s against a central difference (truncation ~δ², rounding ~ε|x|/δ).
            let dr = 1e-5;
            let (a, b) = (
                plant.step(&params(IPM_R_S + dr, IPM_K_E), i, u0, w_m).unwrap(),
                plant.step(&params(IPM_R_S - dr, IPM_K_E), i, u0, w_m).unwrap(),
            );
            let fd = [(a[0] - b[0]) / (2.0 * dr), (a[1] - b[1]) / (2.0 * dr)];
            let er = (d_r_s[0] - fd[0]).hypot(d_r_s[1] - fd[1]) / (1e-300 + d_r_s[0].hypot(d_r_s[1]));
            worst_r = worst_r.max(er);
        }
    }
    eprintln!(
        "salient step derivatives: K_e vs unit step rel. {worst_k:.1e}, R_s vs central difference rel. {worst_r:.1e}"
    );
    assert!(worst_k < 1e-12, "{worst_k:e}");
    assert!(worst_r < 1e-6, "{worst_r:e}");
    // Cost (printed, not asserted): one step with derivatives against the four plain steps
    // of the difference route (main, unit K_e, R_s ± δ).
    let mut plant = ExactPlant::new(IPM_N_P, h, true, VoltageHold::Stator).unwrap();
    let p = params(IPM_R_S, IPM_K_E);
    let n = 20_000;
    let t0 = std::time::Instant::now();
    let mut acc = 0.0;
    for k in 0..n {
        let w = 300.0 * (k as f64 * 1e-3).sin();
        acc += plant.step_derivatives(&p, [1.0, 2.0], C64::new(5.0, 30.0), w).unwrap().d_r_s[0];
    }
    let t_der = t0.elapsed().as_secs_f64() * 1e9 / n as f64;
    let t0 = std::time::Instant::now();
    for k in 0..n {
        let w = 300.0 * (k as f64 * 1e-3).sin();
        for _ in 0..4 {
            acc += plant.step(&p, [1.0, 2.0], C64::new(5.0, 30.0), w).unwrap()[0];
        }
    }
    let t_fd = t0.elapsed().as_secs_f64() * 1e9 / n as f64;
    eprintln!("step_derivatives {t_der:.0} ns, four plain steps {t_fd:.0} ns ({acc:.1e})");
    // A surface-magnet plant has no derivatives to offer; R_s = 0 is accepted.
    let spm = ExactPlant::new(IPM_N_P, h, false, VoltageHold::Stator).unwrap();
    assert!(matches!(
        spm.step_derivatives(&params(IPM_R_S, IPM_K_E), [1.0, 2.0], C64::default(), 10.0),
        Err(Error::InvalidOption { .. })
    ));
    let ipm = ExactPlant::new(IPM_N_P, h, true, VoltageHold::Stator).unwrap();
    assert!(ipm.step_derivatives(&params(0.0, IPM_K_E), [1.0, 2.0], C64::default(), 10.0).is_ok());
}

#[test]
fn salient_lyapunov_and_relay_converge_from_80_percent() {
    let h = 1e-4;
    let e = ipm_plant(60_000, h, 200.0, VoltageHold::Stator, 11);
    for (adaptation, gamma_ke) in [(Adaptation::Lyapunov, 0.001), (Adaptation::Relay, 0.1)] {
        let cfg = MrasConfig { adaptation, gamma_ke, ..ipm_config(h, VoltageHold::Stator) };
        let start = std::time::Instant::now();
        let tr = run(&e, &cfg);
        let ns = start.elapsed().as_secs_f64() * 1e9 / tr.t.len() as f64;
        let (ek, er) = tail_errors(&tr, 10_000, IPM_K_E, IPM_R_S);
        eprintln!(
            "salient {adaptation:?}: final K_e rel. error {:.2e}, R_s {:.2e}; over the last 1 s max K_e {ek:.2e}, R_s {er:.2e} ({ns:.0} ns per sample with track)",
            rel(tr.final_estimate.k_e, IPM_K_E),
            rel(tr.final_estimate.r_s, IPM_R_S)
        );
        assert!(ek < 5e-3, "{adaptation:?}: K_e {ek:e}");
        assert!(er < 2e-2, "{adaptation:?}: R_s {er:e}");
    }
    // The surface-magnet observer (l_s = L_d) on the same record is biased: the reason for
    // the salient one.
    let spm = run(&e, &MrasConfig { l_q: None, ..ipm_config(h, VoltageHold::Stator) });
    eprintln!(
        "surface-magnet observer on the salient record: final K_e rel. error {:.2e}, R_s {:.2e}",
        rel(spm.final_estimate.k_e, IPM_K_E),
        rel(spm.final_estimate.r_s, IPM_R_S)
    );
}

#[test]
fn salient_settings_validate_and_old_configs_parse() {
    let good = ipm_config(1e-4, VoltageHold::Stator);
    assert!(good.salient());
    assert!(!MrasConfig { l_q: Some(IPM_L_D), ..good.clone() }.salient());
    for bad in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        match Mras::try_new(MrasConfig { l_q: Some(bad), ..good.clone() }) {
            Err(Error::InvalidOption { option, .. }) => assert_eq!(option, "l_q"),
            other => panic!("{bad}: {other:?}"),
        }
    }
    // A configuration written before l_q existed parses to the surface-magnet observer, and
    // one without l_q is written without it.
    let old = r#"{"n_p": 4, "l_s": 0.0045, "h": 0.0001, "k_e0": 0.5, "r_s0": 0.7}"#;
    let cfg: MrasConfig = serde_json::from_str(old).unwrap();
    assert_eq!(cfg.l_q, None);
    assert!(!serde_json::to_string(&cfg).unwrap().contains("l_q"));
    let back: MrasConfig = serde_json::from_str(&serde_json::to_string(&good).unwrap()).unwrap();
    assert_eq!(back, good);
    // Garbage samples: an error or finite estimates, never a panic.
    let mut m = Mras::try_new(MrasConfig { gamma_ke: 10.0, gamma_rs: -1e4, ..good }).unwrap();
    for s in [
        Sample { i_d: 1.0, i_q: 2.0, u_d: 3.0, u_q: 40.0, w_m: 50.0 },
        Sample { i_d: 1e300, i_q: -1e300, u_d: 1e300, u_q: 0.0, w_m: 1e300 },
        Sample { i_d: f64::NAN, ..Default::default() },
        Sample { i_d: -8.0, i_q: 2.0, u_d: -3.0, u_q: 4.0, w_m: 0.0 },
    ] {
        if let Ok(est) = m.update(&s) {
            assert!(est.k_e.is_finite() && est.r_s.is_finite() && est.r_s >= 0.0, "{est:?}");
        }
    }
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn salient_logs_with_d_injection() {
    require_shared!();
    // Gains per log. motulator's machine (L_q = 7.5 mH, up to 230 rad/s): the thesis
    // defaults. gym-electric-motor's (L_d = 0.5 mH, L_q = 1.3 mH, up to 300 rad/s, R_s =
    // 0.03 Ω): the K_e rate scales as γ_Ke emf²/L_q², about 57 times motulator's at one γ_Ke,
    // so γ_Ke = 1e-5 (about motulator's rate); its R_s is 12 times smaller, so the current
    // noise of the noisy copy (0.65 A rms) and the operating point's own i_d move R̂_s more:
    // γ_Rs = −1, adapting while |i_d| > 5 A (the injection is −50 A and +25 A). The same
    // gains on both gym-electric-motor logs.
    for (stem, hold, gamma_ke, gamma_rs, i_d_threshold) in [
        ("ipm_moves_idinj", VoltageHold::Stator, 0.001, -10.0, 0.5),
        ("gem_ipm_moves_idinj", VoltageHold::Dq, 1e-5, -1.0, 5.0),
        ("gem_ipm_moves_idinj_noisy", VoltageHold::Dq, 1e-5, -1.0, 5.0),
    ] {
        let (e, truth) = crate::common::load(stem);
        assert!(truth.salient, "{stem}");
        let cfg = MrasConfig {
            n_p: truth.n_p,
            l_s: truth.l_d,
            l_q: Some(truth.l_q),
            k_e0: 0.8 * truth.k_e,
            r_s0: 0.8 * truth.r_s,
            gamma_ke,
            gamma_rs,
            i_d_threshold,
            hold,
            ..Default::default()
        };
        let tr = run(&e, &cfg);
        let n = tr.t.len();
        let (ek, er) = tail_errors(&tr, n / 10, truth.k_e, truth.r_s);
        let (fk, fr) = (rel(tr.final_estimate.k_e, truth.k_e), rel(tr.final_estimate.r_s, truth.r_s));
        eprintln!(
            "{stem}: final K_e {:.6} (truth {:.6}, rel. {fk:.2e}), R_s {:.5} (truth {}, rel. {fr:.2e}); last 10 % max rel. error K_e {ek:.2e}, R_s {er:.2e}",
            tr.final_estimate.k_e, truth.k_e, tr.final_estimate.r_s, truth.r_s
        );
        assert!(relative_eq!(tr.final_estimate.k_e, truth.k_e, max_relative = 0.01), "{stem}: K_e {fk:e}");
        assert!(fr < 0.05, "{stem}: R_s {fr:e}");
    }
}
