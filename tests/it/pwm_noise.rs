//! Issue 42 under current noise: PWM fits from the reference whose measured current is
//! noisy. Soft legs keep their width, a given width is fitted through the same stages
//! (mask, compensation), and a drive without a phase-locked loop keeps the logged frame.

use super::pwm_model::{pwm_fit, truth};
use greybox::drive::{DriveConfig, PwmPlant, SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::PwmInverter;

/// The largest |z| of the motor's parameters (r_s, l_s, k_e) of `fit` against `cfg`'s.
fn worst_motor_z(fit: &greybox::pmsm::PmsmFit, cfg: &DriveConfig, t_d: f64, u_th: f64) -> f64 {
    ["r_s", "l_s", "k_e"]
        .iter()
        .zip(truth(cfg, t_d, u_th))
        .map(|(n, w)| {
            let p = fit.parameter(n).unwrap();
            let z = (p.value - w) / p.std_error;
            eprintln!("{n}: {:+.3} %, z {z:.2}", 100.0 * (p.value / w - 1.0));
            z.abs()
        })
        .fold(0.0, f64::max)
}

fn untrusted(fit: &greybox::pmsm::PmsmFit) -> Vec<&str> {
    fit.report.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.as_str()).collect()
}

/// `exp3` through the switching inverter `plant` with 0.05 A of noise per phase, `duration`
/// s at the sample time `h` \[s\] (the scenario's when `None`), noise seed `seed`.
fn noisy_log(
    plant: PwmPlant,
    h: Option<f64>,
    duration: f64,
    seed: u64,
) -> (greybox::Experiment, DriveConfig) {
    let cfg = scenario("exp3", SPM_MOTOR).unwrap();
    let mut inverter = cfg.inverter.clone();
    inverter.pwm = Some(plant);
    let sensors = greybox::drive::Sensors { current_noise: 0.05, ..Default::default() };
    let control = greybox::drive::Control { h: h.unwrap_or(cfg.control.h), ..cfg.control.clone() };
    let cfg = DriveConfig { inverter, sensors, control, duration, seed, ..cfg };
    (simulate_drive(&cfg).unwrap().experiment, cfg)
}

/// Noise on the measured current of an inverter whose legs switch softly (a smooth leg
/// state of 0.05 A): the unmasked width, wider than the noise makes of a hard switch, is
/// held and its criterion compensated through the smooth legs' transition; the fit is
/// trusted and the motor's parameters are within 3 standard errors (before, the fit took
/// the sign, which does not describe such legs: on motulator's 4 kHz log R_s 6 % high at
/// 6 standard errors, and the fit was untrusted). The hard switch under the same noise
/// takes the sign.
#[test]
fn a_soft_switch_under_noise_keeps_its_width() {
    for (i_w, seed) in [(0.05, 5), (0.0, 5)] {
        let (e, cfg) = noisy_log(PwmPlant { t_d: 3e-6, u_th: 1.0, i_w, levels: 0 }, None, 2.0, seed);
        let fit = pwm_fit(&e, &cfg, PwmInverter { estimate_i_w: true, ..Default::default() });
        let codes = untrusted(&fit);
        let note = fit.pmsm_notes.iter().find(|n| n.contains("leg state on")).expect("the leg-state choice");
        eprintln!("i_w {i_w}: {codes:?} {note}");
        assert_eq!(note.contains("the legs switch softly"), i_w > 0.0, "{note}");
        assert_eq!(fit.parameter("i_w").is_some(), i_w > 0.0, "{note}");
        let worst = worst_motor_z(&fit, &cfg, 3e-6, 1.0);
        eprintln!("largest |z| of the motor's parameters {worst:.2}");
        if i_w > 0.0 {
            assert!(codes.is_empty(), "{codes:?}");
            assert!(worst < 3.0, "|z| {worst}");
        }
    }
}

/// Under current noise, a drive that advances its reference with the logged speed (the
/// drive simulator's) keeps the logged frame: the final fit at the searched loop is
/// compared with the fit at the logged angle and speed by the compensated criterion of
/// each (before, the search and the fit settled together at a loop of 758–980 rad/s with
/// `l_s` 1.1–2.7 % low, z down to −3.3 on this seed, trusted). 4 kHz, 1 µs, 1.5 V, 0.05 A
/// per phase.
#[test]
fn under_noise_the_logged_frame_is_kept_where_the_drive_has_no_loop() {
    let plant = PwmPlant { t_d: 1e-6, u_th: 1.5, i_w: 0.0, levels: 4096 };
    let (e, cfg) = noisy_log(plant, Some(1.25e-4), 4.0, 3);
    let inverter = PwmInverter { levels: Some(4096), search_speed_pll: true, ..Default::default() };
    let fit = pwm_fit(&e, &cfg, inverter);
    let note = fit
        .pmsm_notes
        .iter()
        .find(|n| n.contains("compensated criterion at its own"))
        .expect("the comparison");
    eprintln!("{note}");
    assert!(note.ends_with("the logged"), "{note}");
    let worst = worst_motor_z(&fit, &cfg, 1e-6, 1.5);
    assert!(worst < 2.5, "|z| {worst}");
}

/// A leg-state width given (`--leg-state-width 0.05`, the plant's) under 0.05 A of noise:
/// the fit runs through the stages an estimated width does (the loop, the mask, the
/// compensation through the smooth legs' transition) and is trusted within 3 standard
/// errors (before, it ran unmasked and uncompensated: L 7.8 % low, `segments_disagree`).
#[test]
fn a_given_width_under_noise_is_masked_and_compensated() {
    let (e, cfg) = noisy_log(PwmPlant { t_d: 3e-6, u_th: 1.0, i_w: 0.05, levels: 0 }, None, 2.0, 5);
    let fit = pwm_fit(&e, &cfg, PwmInverter { i_w: Some(0.05), ..Default::default() });
    let codes = untrusted(&fit);
    assert!(fit.pmsm_notes.iter().any(|n| n.contains("PWM sign mask")), "{:?}", fit.pmsm_notes);
    assert!(fit.pmsm_notes.iter().any(|n| n.contains("subtracts its share")), "{:?}", fit.pmsm_notes);
    let worst = worst_motor_z(&fit, &cfg, 3e-6, 1.0);
    assert!(codes.is_empty(), "{codes:?}");
    assert!(worst < 3.0, "|z| {worst}");
}
