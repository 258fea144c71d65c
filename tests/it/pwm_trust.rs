//! Issue 28, PWM: a fit from the reference voltage with the inverter model is trusted only
//! when its error is inside its intervals. The logs' consecutive parts must agree
//! (`segments_disagree` otherwise), and a masked fit must not move when more current noise
//! is added (`noise_bias` otherwise). The drive simulator's exact dead-time logs pass both.

use crate::common::rel;
use greybox::drive::{DriveConfig, Inverter, SPM_MOTOR, Sensors, scenario, simulate_drive};
use greybox::pmsm::{
    DeadTimeMask, HoldChoice, InverterModel, MotorKind, PmsmFit, PmsmFitOptions, VoltageInput, fit_pmsm,
};

/// The README's option set for a PWM log: the reference voltage, the inverter model, the
/// automatic dead-time mask.
fn pwm_options(n_p: u32, model: MotorKind) -> PmsmFitOptions {
    let inverter = Some(InverterModel { mask: Some(DeadTimeMask::Auto), ..Default::default() });
    PmsmFitOptions { model, input: VoltageInput::REFERENCE, inverter, ..PmsmFitOptions::new(n_p) }
}

/// The number `key` (`value`, `std_error`) of parameter `name` in a JSON report.
fn field(report: &serde_json::Value, name: &str, key: &str) -> f64 {
    report["parameters"].as_array().unwrap().iter().find(|p| p["name"] == name).unwrap()[key]
        .as_f64()
        .unwrap()
}

fn codes(fit: &PmsmFit) -> Vec<&str> {
    fit.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.as_str()).collect()
}

/// A drive-simulator log with a 6 V dead-time voltage (the model's own inverter) and
/// `current_noise` \[A\] on the phase currents.
fn dead_time_log(name: &str, v_dt: f64, current_noise: f64) -> (greybox::Experiment, greybox::drive::Truth) {
    let cfg = scenario(name, SPM_MOTOR).unwrap();
    let cfg = DriveConfig {
        inverter: Inverter { v_dt, ..cfg.inverter.clone() },
        sensors: Sensors { current_noise, ..cfg.sensors.clone() },
        seed: 11,
        ..cfg
    };
    let log = simulate_drive(&cfg).unwrap();
    (log.experiment, log.truth)
}

/// Noise-free: the masked fit is exact, both checks stay silent, the fit is trusted (exp3
/// with 9.2 V, the case that once exited 3 for a late voltage).
#[test]
fn exact_dead_time_logs_pass_both_checks() {
    let (e, t) = dead_time_log("exp3", 9.2, 0.0);
    let fit = fit_pmsm(&[e], &PmsmFitOptions { hold: HoldChoice::Stator, ..pwm_options(4, MotorKind::Spm) })
        .unwrap();
    assert!(rel(fit.parameter("r_s").unwrap().value, t.start.r_s) < 1e-6);
    assert!(fit.trusted(), "{:?}", fit.warnings);
}

/// 0.05 A of current noise biases the masked one-step fit (r_s about 12 % high at 5 standard
/// errors on this scenario): the noise check makes it untrusted.
#[test]
fn current_noise_bias_of_a_masked_fit_is_untrusted() {
    let (e, t) = dead_time_log("exp6", 6.0, 0.05);
    let fit = fit_pmsm(&[e], &pwm_options(4, MotorKind::Spm)).unwrap();
    let r_s = fit.parameter("r_s").unwrap();
    let z = (r_s.value - t.start.r_s) / r_s.std_error;
    eprintln!(
        "exp6, 0.05 A: r_s {:+.2} % ({z:+.1} se); untrusted: {:?}",
        100.0 * (r_s.value / t.start.r_s - 1.0),
        codes(&fit)
    );
    assert!(codes(&fit).contains(&"noise_bias"), "{:?}", fit.warnings);
    let w = fit.warnings.iter().find(|w| w.code == "noise_bias").unwrap();
    assert!(w.message.contains("r_s by +"), "{}", w.message);
}

/// The three development PWM logs with the one option set: each is either within the issue's
/// tolerances with the truth inside its 95 % intervals, or untrusted. Measured: all three
/// untrusted by the segment check (r_s, l_s off by up to 2.8 % and 1.1 %, |z| up to 6.5).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn pwm_logs_are_right_or_untrusted() {
    crate::common::require_shared!();
    for (stem, model) in [
        ("servo_spm_pwm_deadtime_idinj", MotorKind::Spm),
        ("servo_spm_pwm_deadtime_lowdrop", MotorKind::Spm),
        ("ipm_pwm_deadtime_idinj", MotorKind::Ipm),
    ] {
        let (e, t) = crate::common::load(stem);
        let fit = fit_pmsm(&[e], &pwm_options(t.n_p, model)).unwrap();
        let truth: &[(&str, f64, f64)] = match model {
            MotorKind::Spm => &[("r_s", t.r_s, 5e-3), ("l_s", t.l_d, 5e-3), ("k_e", t.k_e, 5e-4)],
            MotorKind::Ipm => {
                &[("r_s", t.r_s, 5e-3), ("l_d", t.l_d, 5e-3), ("l_q", t.l_q, 5e-3), ("k_e", t.k_e, 5e-4)]
            }
        };
        let right = truth.iter().all(|(n, v, tol)| {
            let p = fit.parameter(n).unwrap();
            rel(p.value, *v) <= *tol && p.ci95[0] <= *v && *v <= p.ci95[1]
        });
        eprintln!("{stem}: right {right}, untrusted {:?}", codes(&fit));
        assert!(right || !fit.trusted(), "{stem}: wrong and trusted: {:?}", fit.warnings);
        if !right {
            assert!(codes(&fit).contains(&"segments_disagree"), "{stem}: {:?}", fit.warnings);
        }
    }
}

/// A switching-resolved fit from the reference with the wrong computational delay is
/// untrusted (`delay`): the check's neighbours, each through the fit's stages from the
/// least-squares start, find a far lower loss at the drive's delay of one sample; the right
/// delay passes without the warning (the drive simulator's switching inverter, 3 µs and
/// 1 V, noise-free).
#[test]
fn a_wrong_delay_is_named_on_a_pwm_fit() {
    let cfg = scenario("exp3", SPM_MOTOR).unwrap();
    let mut inverter = cfg.inverter.clone();
    inverter.pwm = Some(greybox::drive::PwmPlant { t_d: 3e-6, u_th: 1.0, i_w: 0.0, levels: 0 });
    let cfg = DriveConfig { inverter, duration: 0.6, seed: 3, ..cfg };
    let e = simulate_drive(&cfg).unwrap().experiment;
    let delay_warned = |delay: usize| {
        let options = PmsmFitOptions {
            input: VoltageInput::Reference { delay, advance: 1.5, speed_pll: None },
            pwm: Some(greybox::pmsm::PwmInverter { u_dc: Some(cfg.control.u_dc), ..Default::default() }),
            ..PmsmFitOptions::new(cfg.motor.n_p)
        };
        let fit = fit_pmsm(std::slice::from_ref(&e), &options).unwrap();
        let warned = fit.warnings.iter().any(|w| w.code == "delay" && w.untrusted);
        eprintln!("delay {delay}: untrusted {:?}", codes(&fit));
        (warned, fit)
    };
    for wrong in [0, 2] {
        let (warned, fit) = delay_warned(wrong);
        assert!(warned && !fit.trusted(), "delay {wrong}: {:?}", fit.warnings);
    }
    let (warned, fit) = delay_warned(1);
    assert!(!warned, "{:?}", fit.warnings);
    assert!(rel(fit.parameter("r_s").unwrap().value, cfg.motor.r_s) < 3e-3, "{:?}", fit.parameters);
}

/// Short cuts of a PWM log fitted from the reference land in the same minimum as the whole
/// log: cut at 1.75 s the sign's fit on the unmasked estimate's mask had stopped at 2.4e-3
/// and lost to the width's 4.8e-4, whose final fit then ended at 2.2e-2 with its parts
/// disagreeing (exit 3); cut at 1.8 s the residual's rounding, read as noise, made the
/// width's `leg_state_unresolved` on a sign that fitted 2000 times better. Both exit 0
/// with every estimate within 0.01 % (the shared 3 µs log, noise-free). At 1.75 s the
/// unmasked width (5.5e-5 A) lies inside the sign mask's margin and is taken for the sign
/// (`NEGLIGIBLE_WIDTH`), without the width's masked fit; before that rule the sign was
/// refitted on its own mask and won there.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn short_cuts_of_a_pwm_log_find_its_minimum() {
    crate::common::require_shared!();
    let stem = "servo_spm_pwm_deadtime_idinj";
    let t = crate::common::truth(stem);
    let log = crate::common::data(&format!("{stem}.csv.gz"));
    let dir = crate::common::TempDir::new("greybox_pwm_cuts");
    for to in ["1.75", "1.8"] {
        let json = dir.join(format!("cut_{to}.json"));
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_greybox"))
            .args(["fit", log.to_str().unwrap(), "-p", "4", "--voltage", "reference", "--inverter", "pwm"])
            .args([
                "--u-dc",
                "560",
                "--pwm-levels",
                "4096",
                "--to",
                to,
                "-q",
                "--json",
                json.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(0), "--to {to}: {}", String::from_utf8_lossy(&out.stderr));
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        if to == "1.75" {
            let notes = report["pmsm_notes"].to_string();
            assert!(
                notes.contains("inside the mask's margin"),
                "--to {to}: the width not taken for the sign"
            );
            // Taken without its masked fit, which could only have started the sign's.
            assert!(notes.contains("not fitted there"), "--to {to}: the negligible width fitted");
        }
        let value = |n: &str| field(&report, n, "value");
        let errors = [("r_s", t.r_s), ("l_s", t.l_d), ("k_e", t.k_e)].map(|(n, w)| (n, rel(value(n), w)));
        eprintln!("--to {to}: relative errors {errors:?}");
        for (n, e) in errors {
            assert!(e < 1e-4, "--to {to}: {n} {e:e}");
        }
    }
}

/// The delay check of a PWM fit compares the delays on the first quarter of a log that
/// holds four times `PWM_DELAY_SAMPLES` and confirms a neighbour named there on the whole
/// log: on the shared 3 µs log (72 000 samples) a wrong `--delay 0` is found on the quarter
/// (at about 10⁸ times the lower loss there; the bound is 10) and confirmed on the whole
/// log, the drive's delay of one sample at millions of times the lower loss.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn a_wrong_delay_is_named_on_the_first_quarter() {
    crate::common::require_shared!();
    let (e, t) = crate::common::load("servo_spm_pwm_deadtime_idinj");
    assert!(e.len() >= 4 * greybox::pmsm::thresholds::PWM_DELAY_SAMPLES);
    let options = PmsmFitOptions {
        input: VoltageInput::Reference { delay: 0, advance: 1.5, speed_pll: None },
        pwm: Some(greybox::pmsm::PwmInverter {
            u_dc: Some(560.0),
            levels: Some(4096),
            search_speed_pll: true,
            ..Default::default()
        }),
        ..PmsmFitOptions::new(t.n_p)
    };
    let fit = fit_pmsm(&[e], &options).unwrap();
    let warning = fit.warnings.iter().find(|w| w.code == "delay").expect("the delay named");
    eprintln!("{}", warning.message);
    assert!(warning.untrusted && warning.message.contains("first quarter"), "{}", warning.message);
    assert!(warning.message.contains("confirmed on the whole"), "{}", warning.message);
    let times: f64 =
        warning.message.split(" times lower").next().unwrap().rsplit(' ').next().unwrap().parse().unwrap();
    assert!(times > 1e4, "{times}");
    assert!(warning.message.contains("delay of 1 samples"), "{}", warning.message);
}

/// The three shared PWM logs with the documented switching-resolved options (docs/options.md:
/// `--voltage reference --inverter pwm --u-dc U --pwm-levels 4096`) exit 0, with R_s and the
/// inductances within 0.3 %, K_e within 0.05 %, the dead time within 5 % and the threshold
/// within 10 % (issue 42), and K_e within 3 standard errors. The low-drop log had regressed
/// to exit 3: a width of 3e-5 A, inside the sign mask's margin of 9e-4 A, won the leg-state
/// comparison and its parts disagreed.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn the_shared_pwm_logs_are_fitted_trusted() {
    crate::common::require_shared!();
    let dir = crate::common::TempDir::new("greybox_pwm_shared");
    for (stem, u_dc, ipm) in [
        ("servo_spm_pwm_deadtime_idinj", "560", false),
        ("servo_spm_pwm_deadtime_lowdrop", "400", false),
        ("ipm_pwm_deadtime_idinj", "400", true),
    ] {
        let t = crate::common::truth(stem);
        let raw: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(crate::common::data(&format!("{stem}.json"))).unwrap(),
        )
        .unwrap();
        let log = crate::common::data(&format!("{stem}.csv.gz"));
        let json = dir.join(format!("{stem}.json"));
        let n_p = t.n_p.to_string();
        let mut args =
            vec!["fit", log.to_str().unwrap(), "-p", &n_p, "--voltage", "reference", "--inverter", "pwm"];
        args.extend(["--u-dc", u_dc, "--pwm-levels", "4096", "-q", "--json", json.to_str().unwrap()]);
        if ipm {
            args.extend(["--model", "ipm"]);
        }
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_greybox")).args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{stem}: {}", String::from_utf8_lossy(&out.stderr));
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let value = |n: &str| field(&report, n, "value");
        let mut want = vec![("r_s", t.r_s, 3e-3), ("k_e", t.k_e, 5e-4)];
        want.push(("t_d", raw["dead_time_s"].as_f64().unwrap(), 0.05));
        want.push(("u_th", raw["device_threshold_voltage_V"].as_f64().unwrap(), 0.1));
        if ipm {
            want.extend([("l_d", t.l_d, 3e-3), ("l_q", t.l_q, 3e-3)]);
        } else {
            want.push(("l_s", t.l_d, 3e-3));
        }
        for (n, truth, tol) in want {
            let e = rel(value(n), truth);
            eprintln!("{stem}: {n} {:+.4} %", 100.0 * (value(n) / truth - 1.0));
            assert!(e < tol, "{stem}: {n} {} against {truth}", value(n));
        }
        // K_e within 3 of its noise-free standard errors: with the chord of the sampled
        // speeds as each period's mean (no scale to the angle, `pwm/angle_speed.rs`) it was
        // low by 3-9 ppm, 13-25 standard errors.
        let z = (value("k_e") - t.k_e) / field(&report, "k_e", "std_error");
        eprintln!("{stem}: k_e z {z:+.2}");
        assert!(z.abs() <= 3.0, "{stem}: k_e z {z}");
    }
}
