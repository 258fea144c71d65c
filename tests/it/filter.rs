//! Butterworth design and zero-phase filtering: frequency response, passband exactness,
//! scipy cross-check, bad options.
// The scipy reference numbers are pasted as printed (17 significant digits).
#![allow(clippy::excessive_precision)]

use approx::assert_relative_eq;
use greybox::Error;
use greybox::estimate::{Butterworth, MAX_ORDER};
use std::f64::consts::{FRAC_1_SQRT_2, PI};

const H: f64 = 1e-4; // 10 kHz, as the servo logs

#[test]
fn response_is_one_at_dc_and_minus_3_db_at_cutoff() {
    for order in [2, 4, 6, 8] {
        for fc in [50.0, 500.0, 2000.0, 4900.0] {
            let bw = Butterworth::try_new(order, fc, H).unwrap();
            assert_eq!(bw.sections().len(), order / 2);
            let dc = bw.frequency_response(0.0);
            assert_relative_eq!(dc.re, 1.0, epsilon = 1e-12);
            assert!(dc.im.abs() < 1e-12);
            let at_fc = bw.frequency_response(fc).norm();
            assert_relative_eq!(at_fc, FRAC_1_SQRT_2, epsilon = 1e-12);
            // Forward-backward: |H|² = 1/2 at the cutoff.
            assert_relative_eq!(at_fc * at_fc, 0.5, epsilon = 1e-12);
            // Monotone low-pass: less above the cutoff, zero at Nyquist.
            assert!(bw.frequency_response(0.5 * (fc + 0.5 / H)).norm() < at_fc);
            assert!(bw.frequency_response(0.5 / H).norm() < 1e-12);
        }
    }
}

/// scipy 1.17.1: `signal.butter(4, 0.1, output='sos')` and `signal.butter(6, 0.05,
/// output='sos')` (Wn = 2 f_c h relative to Nyquist), printed with 17 digits.
#[test]
fn coefficients_match_scipy() {
    let cases: [(usize, f64, f64, &[[f64; 2]]); 2] = [
        (
            4,
            0.1,
            4.1659920440659937e-04,
            &[
                [-1.4796742169311934e+00, 5.5582154328248889e-01],
                [-1.7009643319435257e+00, 7.8849973981529786e-01],
            ],
        ),
        (
            6,
            0.05,
            1.7536549719840554e-07,
            &[
                [-1.7160712906118616e+00, 7.3746233511051895e-01],
                [-1.7786317778245846e+00, 8.0080264666570733e-01],
                [-1.8985094164249083e+00, 9.2217457511035283e-01],
            ],
        ),
    ];
    for (order, wn, gain, dens) in cases {
        let bw = Butterworth::try_new(order, wn / (2.0 * H), H).unwrap();
        let s = bw.sections();
        assert_eq!(s.len(), dens.len());
        for (sec, den) in s.iter().zip(dens) {
            assert_eq!(sec.a[0], 1.0);
            assert_relative_eq!(sec.a[1], den[0], epsilon = 1e-12);
            assert_relative_eq!(sec.a[2], den[1], epsilon = 1e-12);
            // Numerator shape (1 + z⁻¹)²; scipy keeps the gain in the first section.
            assert_relative_eq!(sec.b[1], 2.0 * sec.b[0], max_relative = 1e-15);
            assert_relative_eq!(sec.b[2], sec.b[0], max_relative = 1e-15);
        }
        let total: f64 = s.iter().map(|x| x.b[0]).product();
        assert_relative_eq!(total, gain, max_relative = 1e-12);
    }
}

fn test_signal() -> Vec<f64> {
    (0..200)
        .map(|k| k as f64)
        .map(|k| (0.05 * k).sin() + 0.5 * (0.31 * k + 0.2).cos() + 0.01 * k - 0.3)
        .collect()
}

/// scipy 1.17.1: with `sos = signal.butter(4, 0.1, output='sos')`, `k = arange(200)`,
/// `x = sin(0.05k) + 0.5 cos(0.31k + 0.2) + 0.01k − 0.3`:
/// `signal.sosfiltfilt(sos, x, padtype='odd', padlen=85)` and `signal.sosfilt(sos, x)`;
/// 85 = ⌈10 τ⌉, τ = −1/ln max|p| = 8.4167 samples.
#[test]
fn filtfilt_matches_scipy_sosfiltfilt() {
    let bw = Butterworth::try_new(4, 500.0, H).unwrap();
    let x = test_signal();
    assert_relative_eq!(bw.time_constant(), 8.416686495717597, max_relative = 1e-12);
    assert_eq!(bw.pad_len(x.len()), 85);
    let y = bw.filtfilt(&x);
    assert_eq!(y.len(), x.len());
    let scipy = [
        (0, 0.19002593725740807),
        (1, 0.09365043318415117),
        (2, 0.0025826018911998105),
        (10, -0.03440191725850791),
        (50, 0.5341196693587841),
        (100, -0.0015088452131615457),
        (150, 1.8972522574484711),
        (190, 1.2558369173659374),
        (197, 1.264694228408558),
        (198, 1.3693670861468101),
        (199, 1.4827251936317338),
    ];
    for (k, v) in scipy {
        assert!((y[k] - v).abs() < 1e-12, "sample {k}: {} vs scipy {v}", y[k]);
    }
    let causal = bw.filter(&x);
    let scipy = [
        (0, 7.916771697510007e-05),
        (1, 0.0006502746069826852),
        (5, 0.02550225812692773),
        (20, 0.03449622649720577),
        (199, 1.2685427501218443),
    ];
    for (k, v) in scipy {
        assert!((causal[k] - v).abs() < 1e-12, "sosfilt sample {k}: {} vs scipy {v}", causal[k]);
    }
}

fn sine(f: f64, n: usize) -> Vec<f64> {
    (0..n).map(|k| (2.0 * PI * f * k as f64 * H + 0.3).sin()).collect()
}

#[test]
fn passband_sinusoid_passes_with_zero_phase() {
    let bw = Butterworth::try_new(4, 500.0, H).unwrap();
    let n = 20_000;
    let x = sine(20.0, n);
    let y = bw.filtfilt(&x);
    let interior = 1000..n - 1000;
    let err = interior.clone().map(|k| (y[k] - x[k]).abs()).fold(0.0, f64::max);
    eprintln!("20 Hz through 500 Hz filtfilt: max interior error {err:.2e}");
    assert!(err < 1e-6, "interior error {err}");
    // Even at the edges the odd padding keeps a smooth record close.
    let edge = (0..n).map(|k| (y[k] - x[k]).abs()).fold(0.0, f64::max);
    eprintln!("20 Hz: max error including edges {edge:.2e}");
    assert!(edge < 1e-3, "edge error {edge}");
}

#[test]
fn at_cutoff_filtfilt_halves_without_phase_shift() {
    let fc = 500.0;
    let bw = Butterworth::try_new(4, fc, H).unwrap();
    let n = 4000;
    let x = sine(fc, n);
    let y = bw.filtfilt(&x);
    let err = (500..n - 500).map(|k| (y[k] - 0.5 * x[k]).abs()).fold(0.0, f64::max);
    eprintln!("f_c through filtfilt: max interior |y − x/2| {err:.2e}");
    assert!(err < 1e-9, "{err}");
    // One causal pass: steady-state amplitude 1/√2 (checks the response against the filter).
    let c = bw.filter(&x);
    let amp = (n - 400..n).map(|k| c[k].abs()).fold(0.0, f64::max);
    assert!((amp - FRAC_1_SQRT_2).abs() < 2e-3, "causal amplitude {amp}");
}

#[test]
fn constant_passes_exactly_and_ramp_has_no_startup_transient() {
    let bw = Butterworth::try_new(4, 200.0, H).unwrap();
    let c = vec![3.25; 500];
    let y = bw.filtfilt(&c);
    let err = y.iter().map(|v| (v - 3.25).abs()).fold(0.0, f64::max);
    assert!(err < 1e-12, "constant: {err}");
    let ramp: Vec<f64> = (0..500).map(|k| 0.01 * k as f64 - 1.0).collect();
    let y = bw.filtfilt(&ramp);
    let err = y.iter().zip(&ramp).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    eprintln!("ramp 0.01/sample: max error {err:.2e}");
    // Measured 1.6e-6 (1.6e-4 of the step per sample); scipy's default padlen = 15 gives 6.4e-2.
    assert!(err < 1e-5, "ramp: {err}");
}

#[test]
fn short_records_work() {
    let bw = Butterworth::try_new(4, 500.0, H).unwrap();
    assert!(bw.filtfilt(&[]).is_empty());
    assert_relative_eq!(bw.filtfilt(&[2.0])[0], 2.0, epsilon = 1e-12);
    let y = bw.filtfilt(&[1.0, 2.0, 3.0]);
    assert_eq!(y.len(), 3);
    assert!(y.iter().all(|v| v.is_finite()));
}

fn option_of(e: Error) -> String {
    match e {
        Error::InvalidOption { option, .. } => option,
        other => panic!("expected InvalidOption, got {other}"),
    }
}

#[test]
fn bad_options_are_errors() {
    for order in [0, 1, 3, 5, MAX_ORDER + 2] {
        assert_eq!(option_of(Butterworth::try_new(order, 500.0, H).unwrap_err()), "order");
    }
    for fc in [0.0, -1.0, 5000.0, 6000.0, f64::NAN, f64::INFINITY] {
        let e = Butterworth::try_new(4, fc, H).unwrap_err();
        assert!(e.to_string().contains("cutoff"), "{e}");
        assert_eq!(option_of(e), "cutoff");
    }
    for h in [0.0, -1e-4, f64::NAN] {
        assert!(matches!(Butterworth::try_new(4, 500.0, h), Err(Error::InvalidSampleTime { .. })));
    }
    // A filter for 10 kHz refuses an 8 kHz log.
    let s = greybox::pmsm::DqSignals {
        u_d: vec![0.0; 32],
        u_q: vec![0.0; 32],
        i_d: vec![0.0; 32],
        i_q: vec![0.0; 32],
        w_m: vec![0.0; 32],
        ..Default::default()
    };
    let e = s.into_experiment("x", 1.25e-4).unwrap();
    let bw = Butterworth::try_new(4, 500.0, H).unwrap();
    assert_eq!(option_of(bw.filtfilt_experiment(&e, &["theta_m"]).unwrap_err()), "sample time");
}
