//! The extended Kalman filter of R_s and K_e (issue 46): convergence on exact logs from
//! wrong starts (surface and salient), its intervals' coverage over time by Monte Carlo on
//! drive-simulator logs with a winding heating up and a magnet step, its settings' errors,
//! and `greybox track --estimator ekf`.

use crate::common::{Rng, exciting_signals, rel, simulate_into};
use greybox::Error;
use greybox::drive::{DriveConfig, Profile, SPM_MOTOR, scenario, simulate_drive};
use greybox::online::{KalmanNoise, MrasConfig, Trajectory, track_kalman};
use greybox::pmsm::{PmsmIpm, PmsmSpm, VoltageHold};

const N_P: u32 = 4;

/// The last point's errors relative to the truth and in standard errors: (K_e, R_s).
fn final_errors(tr: &Trajectory, k_e: f64, r_s: f64) -> ((f64, f64), (f64, f64)) {
    let f = &tr.final_estimate;
    let (k_se, r_se) = tr.final_se().expect("the filter gives standard errors");
    ((rel(f.k_e, k_e), (f.k_e - k_e) / k_se), (rel(f.r_s, r_s), (f.r_s - r_s) / r_se))
}

#[test]
fn converges_from_wrong_starts_on_exact_logs_of_both_machines() {
    let (r_s, l_s, k_e, h) = (0.9, 4.5e-3, 0.54, 1e-4);
    for hold in [VoltageHold::Stator, VoltageHold::Dq] {
        let s = exciting_signals(40_000, h, 200.0, 10.0, k_e, &mut Rng(7));
        let log = simulate_into(&PmsmSpm::new(N_P, hold), &[r_s, l_s, k_e], h, s);
        let cfg =
            MrasConfig { n_p: N_P, l_s, h, k_e0: 0.8 * k_e, r_s0: 1.3 * r_s, hold, ..Default::default() };
        let tr = track_kalman(&log, &cfg, None).unwrap();
        let ((k_rel, k_z), (r_rel, r_z)) = final_errors(&tr, k_e, r_s);
        assert!(k_rel < 1e-4 && r_rel < 1e-3, "{hold:?}: K_e {k_rel:e}, R_s {r_rel:e}");
        assert!(k_z.abs() < 3.0 && r_z.abs() < 3.0, "{hold:?}: z {k_z}, {r_z}");
        assert_eq!((tr.k_e_se.len(), tr.r_s_se.len()), (tr.t.len(), tr.t.len()));
    }
    // A salient machine through the exact salient step.
    let (l_d, l_q) = (3e-3, 6e-3);
    let s = exciting_signals(40_000, h, 200.0, 10.0, k_e, &mut Rng(11));
    let log = simulate_into(&PmsmIpm::new(N_P, VoltageHold::Stator), &[r_s, l_d, l_q, k_e], h, s);
    let cfg = MrasConfig {
        n_p: N_P,
        l_s: l_d,
        l_q: Some(l_q),
        h,
        k_e0: 0.8 * k_e,
        r_s0: 1.3 * r_s,
        ..Default::default()
    };
    let tr = track_kalman(&log, &cfg, None).unwrap();
    let ((k_rel, k_z), (r_rel, r_z)) = final_errors(&tr, k_e, r_s);
    assert!(k_rel < 1e-4 && r_rel < 1e-3, "salient: K_e {k_rel:e}, R_s {r_rel:e}");
    assert!(k_z.abs() < 3.0 && r_z.abs() < 3.0, "salient: z {k_z}, {r_z}");
}

/// Monte Carlo: the drive simulator's Exp 1 (a torque step; R_s +20 % from 9 s to 11 s)
/// with a magnet step ψ_f −5 % at 5 s and 0.05 A current noise, 8 seeds; over every
/// sample after 2 s (the start's convergence), the 95 % band covers the truth in at least
/// 90 % of the samples for R_s and for K_e, averaged over the seeds (50 seeds, measured:
/// 0.965 and 0.962; docs/cli.md).
#[test]
fn intervals_cover_a_heating_winding_and_a_weakened_magnet() {
    let (mut inside_r, mut inside_k, mut total) = (0usize, 0usize, 0usize);
    for seed in 1..=8u64 {
        let mut cfg = scenario("exp1", SPM_MOTOR).unwrap();
        cfg.sensors.current_noise = 0.05;
        cfg.psi_f_factor = Profile(vec![(0.0, 1.0), (5.0, 1.0), (5.0, 0.95)]);
        cfg = DriveConfig { seed, ..cfg };
        let log = simulate_drive(&cfg).unwrap();
        let m = cfg.motor;
        let k_e0 = m.k_e();
        let observer = MrasConfig {
            n_p: m.n_p,
            l_s: m.l_d,
            h: cfg.control.h,
            k_e0: 1.05 * k_e0,
            r_s0: 0.9 * m.r_s,
            ..Default::default()
        };
        let tr = track_kalman(&log.experiment, &observer, None).unwrap();
        for k in 0..tr.t.len() {
            let t = tr.t[k];
            if t < 2.0 {
                continue;
            }
            let (r_true, k_true) = (m.r_s * cfg.r_s_factor.at(t), k_e0 * cfg.psi_f_factor.at(t));
            total += 1;
            inside_r += usize::from((tr.r_s[k] - r_true).abs() <= 1.96 * tr.r_s_se[k]);
            inside_k += usize::from((tr.k_e[k] - k_true).abs() <= 1.96 * tr.k_e_se[k]);
        }
    }
    let (cov_r, cov_k) = (inside_r as f64 / total as f64, inside_k as f64 / total as f64);
    assert!(cov_r >= 0.9 && cov_k >= 0.9, "coverage R_s {cov_r:.3}, K_e {cov_k:.3}");
}

/// Standstill at zero current under 0.05 A of noise (the last 1.75 s of Exp 3, 8 s): the
/// data say nothing of R_s and its band widens by the walk, but the estimate must not move.
/// With the current's model error at `q_i = 0.05 σ_i` the noise drove R_s down steadily,
/// the last estimate 7.7–7.9 % low, z −1.96 … −2.02 on these seeds (mean −1.98); with
/// 0.01 σ_i, z −0.65 … +0.19 (docs/cli.md: 0 of 20 other seeds outside the band).
#[test]
fn r_s_does_not_drift_at_standstill_under_noise() {
    let mut z = Vec::new();
    for seed in 1..=4u64 {
        let mut cfg = scenario("exp3", SPM_MOTOR).unwrap();
        cfg.sensors.current_noise = 0.05;
        cfg.duration = 8.0;
        cfg = DriveConfig { seed, ..cfg };
        let log = simulate_drive(&cfg).unwrap();
        let m = cfg.motor;
        let observer = MrasConfig {
            n_p: m.n_p,
            l_s: m.l_d,
            h: cfg.control.h,
            k_e0: m.k_e(),
            r_s0: m.r_s,
            ..Default::default()
        };
        let tr = track_kalman(&log.experiment, &observer, None).unwrap();
        assert!(tr.t.last().is_some_and(|t| *t > 7.9), "the run reaches the standstill's end");
        z.push(final_errors(&tr, m.k_e(), m.r_s).1.1);
    }
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    assert!(mean.abs() < 1.5, "R_s's last estimate in standard errors: {z:?}");
}

#[test]
fn bad_noise_settings_name_the_field() {
    let s = exciting_signals(100, 1e-4, 100.0, 10.0, 0.5, &mut Rng(1));
    let log = simulate_into(&PmsmSpm::new(N_P, VoltageHold::Stator), &[0.9, 4.5e-3, 0.5], 1e-4, s);
    let cfg = MrasConfig { n_p: N_P, l_s: 4.5e-3, h: 1e-4, k_e0: 0.5, r_s0: 0.9, ..Default::default() };
    let good = KalmanNoise::for_machine(0.01, 0.9, 0.5);
    for (noise, field) in [
        (KalmanNoise { sigma_i: 0.0, ..good }, "sigma_i"),
        (KalmanNoise { q_r_s: -1.0, ..good }, "q_r_s"),
        (KalmanNoise { p0_k_e: f64::NAN, ..good }, "p0_k_e"),
    ] {
        match track_kalman(&log, &cfg, Some(noise)) {
            Err(Error::InvalidOption { option, .. }) => assert_eq!(option, field),
            other => panic!("{field}: {other:?}"),
        }
    }
}
