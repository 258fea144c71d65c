//! Criterion benches of the online estimators (`greybox::online`): one [`Mras::update`]
//! per sample (thesis 5.1) for each adaptation law, one [`Kalman::update`], and [`track`]
//! over the shipped log.
//!
//! - `mras update, <law>`: 10 000 prepared samples per iteration of a synthetic SPM signal
//!   (built here, no files: n_p = 4, L_s = 4.5 mH, h = 100 µs, the speed and the currents
//!   varying around 200 rad/s mechanical, 5 A q and 2 A d, so that the `R_s` law is
//!   active). Criterion's throughput is in samples (elements) per second; the time per
//!   iteration divided by 10 000 is the time of one `update`.
//! - `kalman update, spm`: one [`Kalman::update`] per sample (the extended Kalman filter,
//!   issue 46) on the same samples.
//! - `firmware core`: `greybox-observer`'s MRAS (normalised law) and Kalman filter in
//!   `f64` and `f32` on the same samples.
//! - `track`: [`track`] over `data/sample.csv.gz` (20 000 samples), the trajectory's
//!   vectors included; reading the log is outside the timing.
//!
//! Run: `cargo bench --bench online` (a quick look:
//! `cargo bench --bench online -- --warm-up-time 1 --measurement-time 3`).

use criterion::{Criterion, Throughput, criterion_group};
use greybox::online::{Adaptation, Kalman, KalmanNoise, Mras, MrasConfig, Sample, track};
use greybox::pmsm::read_log;
use std::f64::consts::TAU;
use std::hint::black_box;
use std::path::PathBuf;

/// Pole pairs n_p of the synthetic motor.
const N_P: u32 = 4;
/// Stator inductance L_s [H] of the synthetic motor.
const L_S: f64 = 4.5e-3;
/// Stator resistance R_s [Ω] of the synthetic motor.
const R_S: f64 = 0.9;
/// Back-EMF constant K_e [V s/rad] of the synthetic motor.
const K_E: f64 = 0.54;
/// Sample time h [s].
const H: f64 = 1e-4;
/// Samples per bench iteration.
const N: usize = 10_000;

/// `n` samples of an SPM at a rotating operating point: `ω_m = 200 + 20 sin(2π 3 t)` rad/s
/// (mechanical), `i_d = 2 + 0.5 sin(2π 7 t)` A, `i_q = 5 + sin(2π 11 t)` A, and the voltages
/// of the SPM's voltage equations with those currents (MODEL.md §2):
/// `u = R_s i + L_s di/dt + j ω_e L_s i + j √(2/3) ω_m K_e`, `ω_e = n_p ω_m`.
fn spm_signal(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|k| {
            let t = k as f64 * H;
            let w_m = 200.0 + 20.0 * (TAU * 3.0 * t).sin();
            let w_e = f64::from(N_P) * w_m;
            let (i_d, di_d) = (2.0 + 0.5 * (TAU * 7.0 * t).sin(), 0.5 * TAU * 7.0 * (TAU * 7.0 * t).cos());
            let (i_q, di_q) = (5.0 + (TAU * 11.0 * t).sin(), TAU * 11.0 * (TAU * 11.0 * t).cos());
            let emf = (2.0f64 / 3.0).sqrt() * w_m * K_E;
            Sample {
                i_d,
                i_q,
                u_d: R_S * i_d + L_S * di_d - w_e * L_S * i_q,
                u_q: R_S * i_q + L_S * di_q + w_e * L_S * i_d + emf,
                w_m,
            }
        })
        .collect()
}

/// The observer of the benches: the synthetic motor's known `n_p`, `L_s`, `h`, started 10 %
/// off in `K_e` and 20 % in `R_s`. The relay law uses a larger `γ_Ke` (thesis 5.1.2).
fn config(adaptation: Adaptation) -> MrasConfig {
    let gamma_ke = match adaptation {
        Adaptation::Lyapunov | Adaptation::Normalised => 0.001,
        Adaptation::Relay => 0.001 * 200.0,
    };
    MrasConfig {
        n_p: N_P,
        l_s: L_S,
        h: H,
        adaptation,
        gamma_ke,
        k_e0: 0.9 * K_E,
        r_s0: 1.2 * R_S,
        ..Default::default()
    }
}

fn update(c: &mut Criterion) {
    let samples = spm_signal(N);
    let mut g = c.benchmark_group("mras update");
    g.throughput(Throughput::Elements(N as u64));
    for (name, adaptation) in [
        ("lyapunov", Adaptation::Lyapunov),
        ("relay", Adaptation::Relay),
        ("normalised", Adaptation::Normalised),
    ] {
        // One observer runs on over the iterations: each pass over the samples is one
        // more period of the same signal, as a long log would be.
        let mut mras = Mras::try_new(config(adaptation)).unwrap();
        g.bench_function(format!("{name}, {N} samples"), |b| {
            b.iter(|| {
                for s in &samples {
                    black_box(mras.update(black_box(s)).unwrap());
                }
            })
        });
        let last = mras.output();
        assert!(last.k_e.is_finite() && last.r_s.is_finite(), "{name}: {last:?}");
    }
    g.finish();
}

/// One [`Kalman::update`] per sample (the extended Kalman filter of `R_s` and `K_e`, issue
/// 46), on the same signal and from the same start as the MRAS, current noise 0.01 A.
fn kalman_update(c: &mut Criterion) {
    let samples = spm_signal(N);
    let mut g = c.benchmark_group("kalman update");
    g.throughput(Throughput::Elements(N as u64));
    let cfg = config(Adaptation::Lyapunov);
    let noise = KalmanNoise::for_machine(0.01, cfg.r_s0, cfg.k_e0);
    let mut filter = Kalman::try_new(cfg, noise).unwrap();
    g.bench_function(format!("spm, {N} samples"), |b| {
        b.iter(|| {
            for s in &samples {
                black_box(filter.update(black_box(s)).unwrap());
            }
        })
    });
    g.finish();
}

/// The firmware core (`greybox-observer`, `no_std`) in `f64` and `f32` on the same signal:
/// its MRAS (normalised law) and its Kalman filter, the surface-magnet step, without the
/// crate's conversions. (In this workspace its elementary functions are the host's, as the
/// feature `std` gives them; a `no_std` build takes the `libm` crate's.)
fn core_update(c: &mut Criterion) {
    use greybox_observer as core;
    fn settings<T: core::Real>() -> core::Settings<T> {
        let mut s = core::Settings::new(N_P, T::c(L_S), T::c(H));
        s.adaptation = core::Adaptation::Normalised;
        (s.k_e0, s.r_s0) = (T::c(0.9 * K_E), T::c(1.2 * R_S));
        s
    }
    fn run<T: core::Real, O>(
        g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
        name: &str,
        samples: &[core::Sample<T>],
        mut obs: O,
        update: impl Fn(&mut O, &core::Sample<T>) -> core::Estimates<T>,
    ) {
        g.bench_function(format!("{name}, {N} samples"), |b| {
            b.iter(|| {
                for s in samples {
                    black_box(update(&mut obs, black_box(s)));
                }
            })
        });
    }
    let s64: Vec<core::Sample<f64>> = spm_signal(N)
        .iter()
        .map(|s| core::Sample { i_d: s.i_d, i_q: s.i_q, u_d: s.u_d, u_q: s.u_q, w_m: s.w_m })
        .collect();
    let s32: Vec<core::Sample<f32>> = s64
        .iter()
        .map(|s| core::Sample {
            i_d: s.i_d as f32,
            i_q: s.i_q as f32,
            u_d: s.u_d as f32,
            u_q: s.u_q as f32,
            w_m: s.w_m as f32,
        })
        .collect();
    let mut g = c.benchmark_group("firmware core");
    g.throughput(Throughput::Elements(N as u64));
    let m64 = core::Mras::spm(settings::<f64>()).unwrap();
    run(&mut g, "mras f64", &s64, m64, |m, s| m.update(s).unwrap());
    let m32 = core::Mras::spm(settings::<f32>()).unwrap();
    run(&mut g, "mras f32", &s32, m32, |m, s| m.update(s).unwrap());
    let (c64, c32) = (settings::<f64>(), settings::<f32>());
    let k64 = core::Kalman::spm(c64, core::Noise::for_machine(0.01, c64.r_s0, c64.k_e0)).unwrap();
    run(&mut g, "kalman f64", &s64, k64, |k, s| k.update(s).unwrap());
    let k32 = core::Kalman::spm(c32, core::Noise::for_machine(0.01, c32.r_s0, c32.k_e0)).unwrap();
    run(&mut g, "kalman f32", &s32, k32, |k, s| k.update(s).unwrap());
    // The salient step (the augmented exponential's series) on the same signal: `L_q` a
    // thousandth above `L_d`, so the machine the signal came from is followed and the cost
    // is the series' (it depends on the period's spectral scale, not on the saliency).
    let salient = |c| core::Machine::of(&c, Some(c.l_s * T_Q)).unwrap();
    const T_Q: f64 = 1.001;
    let m64 = core::Mras::new(c64, salient(c64)).unwrap();
    run(&mut g, "mras salient f64", &s64, m64, |m, s| m.update(s).unwrap());
    let k64 =
        core::Kalman::new(c64, salient(c64), core::Noise::for_machine(0.01, c64.r_s0, c64.k_e0)).unwrap();
    run(&mut g, "kalman salient f64", &s64, k64, |k, s| k.update(s).unwrap());
    let salient32 = |c: core::Settings<f32>| core::Machine::of(&c, Some(c.l_s * T_Q as f32)).unwrap();
    let m32 = core::Mras::new(c32, salient32(c32)).unwrap();
    run(&mut g, "mras salient f32", &s32, m32, |m, s| m.update(s).unwrap());
    let k32 =
        core::Kalman::new(c32, salient32(c32), core::Noise::for_machine(0.01, c32.r_s0, c32.k_e0)).unwrap();
    run(&mut g, "kalman salient f32", &s32, k32, |k, s| k.update(s).unwrap());
    g.finish();
}

fn track_sample_log(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/sample.csv.gz");
    let log = read_log(&path, &Default::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    // The module example's settings: the servo log's 4 pole pairs and known L_s = 4.5 mH.
    let cfg = MrasConfig { n_p: 4, l_s: 4.5e-3, k_e0: 0.45, r_s0: 0.7, ..Default::default() };
    let mut g = c.benchmark_group("track");
    // track takes N − 1 observer steps from N samples (the interval-mean speed).
    g.throughput(Throughput::Elements(log.len() as u64 - 1));
    g.bench_function(format!("sample.csv.gz, {} samples", log.len()), |b| {
        b.iter(|| black_box(track(black_box(&log), &cfg).unwrap()))
    });
    g.finish();
}

criterion_group!(online, update, kalman_update, core_update, track_sample_log);

fn main() {
    online();
    Criterion::default().configure_from_args().final_summary();
}
