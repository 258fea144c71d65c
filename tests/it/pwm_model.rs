//! Issue 42: the inverter inside the model. The switching-resolved PWM step
//! (`PmsmPwm`) against the drive simulator's own switching inverter (exact to rounding),
//! against motulator's PWM logs (the shared development logs), its sensitivities against
//! finite differences, its recovery of the motor's and the inverter's parameters, the
//! averaged dead-time model's failure on the same log (the ripple it cannot represent), and
//! the command line's refusals.

use crate::common::rel;
use greybox::drive::{DriveConfig, PwmPlant, SPM_MOTOR, scenario, simulate_drive};
use greybox::model::GreyBoxModel;
use greybox::pmsm::{
    DeadTimeMask, HoldChoice, InverterModel, MotorKind, PmsmFitOptions, PmsmPwm, PwmInverter, VoltageHold,
    VoltageInput, fit_pmsm,
};

/// A drive-simulator log through the switching-resolved inverter: `scenario` for `duration`
/// s with dead time `t_d`, threshold `u_th` and leg-state width `i_w`.
fn pwm_log(name: &str, duration: f64, t_d: f64, u_th: f64, i_w: f64) -> (greybox::Experiment, DriveConfig) {
    let cfg = scenario(name, SPM_MOTOR).unwrap();
    let mut inverter = cfg.inverter.clone();
    inverter.pwm = Some(PwmPlant { t_d, u_th, i_w, levels: 0 });
    let cfg = DriveConfig { inverter, duration, seed: 3, ..cfg };
    (simulate_drive(&cfg).unwrap().experiment, cfg)
}

/// A shared log (`NAME.csv.gz`) with the default columns.
fn shared_log(name: &str) -> greybox::Experiment {
    greybox::pmsm::read_log(crate::common::shared_file(&format!("{name}.csv.gz")), &Default::default())
        .unwrap()
}

fn model(cfg: &DriveConfig, inverter: PwmInverter) -> PmsmPwm {
    let setup = greybox::pmsm::PmsmSetup {
        input: VoltageInput::REFERENCE,
        ..greybox::pmsm::PmsmSetup::new(cfg.motor.n_p, VoltageHold::Stator)
    };
    PmsmPwm::new(setup, MotorKind::Spm, PwmInverter { u_dc: Some(cfg.control.u_dc), ..inverter })
}

/// One-step prediction errors \[A\] of `m` at `theta` on `e` from sample `from`.
fn one_step_errors(m: &PmsmPwm, e: &greybox::Experiment, theta: &[f64], from: usize) -> Vec<f64> {
    let inputs = m.prepare(e).unwrap();
    let c = m.coefficients(theta, &inputs).unwrap();
    let (id, iq) = (e.channel("id").unwrap(), e.channel("iq").unwrap());
    (from..e.len() - 1)
        .map(|k| {
            let mut x = [0.0; 2];
            m.step(&c, &inputs, k, &[id[k], iq[k]], &mut x);
            (x[0] - id[k + 1]).hypot(x[1] - iq[k + 1])
        })
        .collect()
}

/// The PWM fit of `e` from its reference through `inverter` at the log's DC link, without
/// the setup checks.
pub(crate) fn pwm_fit(
    e: &greybox::Experiment,
    cfg: &DriveConfig,
    inverter: PwmInverter,
) -> greybox::pmsm::PmsmFit {
    let options = PmsmFitOptions {
        input: VoltageInput::REFERENCE,
        pwm: Some(PwmInverter { u_dc: Some(cfg.control.u_dc), ..inverter }),
        skip_setup_checks: true,
        ..PmsmFitOptions::new(cfg.motor.n_p)
    };
    fit_pmsm(std::slice::from_ref(e), &options).unwrap()
}

pub(crate) fn truth(cfg: &DriveConfig, t_d: f64, u_th: f64) -> Vec<f64> {
    let p = &cfg.motor;
    vec![p.r_s, p.l_d, p.k_e(), t_d, u_th]
}

/// A 0.2 s `exp3` log of a hard switch (2 µs, 1 V), its model with the carrier rising first,
/// and the true parameters.
fn short_log_at_truth() -> (greybox::Experiment, PmsmPwm, Vec<f64>) {
    let (e, cfg) = pwm_log("exp3", 0.2, 2e-6, 1.0, 0.0);
    let m = model(
        &cfg,
        PwmInverter { first_edge: Some(greybox::pmsm::CarrierEdge::Rising), ..Default::default() },
    );
    (e, m, truth(&cfg, 2e-6, 1.0))
}

/// The simulator's switching inverter is the model's: with the true parameters the
/// one-step prediction reproduces every period after the first to rounding.
#[test]
fn the_pwm_step_reproduces_the_simulators_switching_inverter() {
    let (e, cfg) = pwm_log("exp3", 1.0, 3e-6, 0.9, 0.0);
    let m = model(
        &cfg,
        PwmInverter { first_edge: Some(greybox::pmsm::CarrierEdge::Rising), ..Default::default() },
    );
    let worst = one_step_errors(&m, &e, &truth(&cfg, 3e-6, 0.9), 2).into_iter().fold(0.0, f64::max);
    assert!(worst < 1e-9, "largest one-step error {worst:e} A");
    // Another dead time is visibly another model: the step resolves the blanking.
    let off = one_step_errors(&m, &e, &truth(&cfg, 2.7e-6, 0.9), 2).into_iter().fold(0.0, f64::max);
    assert!(off > 1e-4, "a 10 % shorter dead time moves the prediction by only {off:e} A");
}

/// The analytic (forward-mode) sensitivities of the step, including those through the
/// switching instants the dead time moves, equal central differences (smooth leg state, so
/// that the differences exist).
#[test]
fn the_pwm_sensitivities_are_the_steps_derivatives() {
    let (e, cfg) = pwm_log("exp3", 0.6, 2e-6, 1.0, 0.05);
    let m = model(&cfg, PwmInverter { estimate_i_w: true, ..Default::default() });
    let theta = [cfg.motor.r_s, cfg.motor.l_d, cfg.motor.k_e(), 2e-6, 1.0, 0.05];
    let inputs = m.prepare(&e).unwrap();
    let c = m.coefficients(&theta, &inputs).unwrap();
    let sens = m.sensitivities().expect("analytic sensitivities");
    let (id, iq) = (e.channel("id").unwrap(), e.channel("iq").unwrap());
    let n = theta.len();
    for k in [1500, 3000, 4500, 5900] {
        let x = [id[k], iq[k]];
        let (mut xn, mut sn) = ([0.0; 2], vec![0.0; 2 * n]);
        sens.step_sensitivity(&c, &inputs, k, &x, &vec![0.0; 2 * n], &mut xn, &mut sn);
        for j in 0..n {
            let d = 1e-5 * theta[j];
            let step = |s: f64| {
                let mut t = theta;
                t[j] += s * d;
                let c = m.coefficients(&t, &inputs).unwrap();
                let mut out = [0.0; 2];
                m.step(&c, &inputs, k, &x, &mut out);
                out
            };
            let (p, q) = (step(1.0), step(-1.0));
            for i in 0..2 {
                let fd = (p[i] - q[i]) / (2.0 * d);
                let an = sn[i * n + j];
                // The central difference's own rounding: each output carries some 100 ulps
                // of the current vector's size (the pieces' rotations mix d and q), divided
                // by the difference's step (2e-8 for 5 A and the k_e step; the fixed 1e-9
                // this replaced was below it for an i_d derivative of 1.8e-4).
                let size = p.iter().chain(&q).fold(0.0_f64, |m, v| m.max(v.abs()));
                let rounding = 100.0 * f64::EPSILON * size / d;
                assert!(
                    (fd - an).abs() <= 1e-5 * fd.abs().max(an.abs()) + rounding.max(1e-9),
                    "k {k}, θ_{j}, x_{i}: {an:e} vs {fd:e}"
                );
            }
        }
    }
}

/// The blocked pass of a predictor that restarts every period (the default gain 1) steps
/// the periods of each block in parallel: its outputs, sensitivities and initial-state
/// directions are the per-sample step's to the bit, for a log longer than several blocks.
#[test]
fn the_parallel_pwm_pass_is_the_per_sample_step() {
    let (e, m, theta) = short_log_at_truth();
    let prep = greybox::model::Prepared::new(&m, &e).unwrap();
    assert!(m.block_kernel().is_some() && prep.n > 3 * greybox::model::BLOCK_LEN, "{} samples", prep.n);
    let c = m.coefficients(&theta, &prep.inputs).unwrap();
    let sens = m.sensitivities().expect("analytic sensitivities");
    let n = theta.len();
    // The per-sample recursion: the state is the output, restarted from the measurement.
    let (mut x, mut s) = (prep.x0.clone(), vec![0.0; 2 * n]);
    let mut expected = Vec::with_capacity(prep.n);
    for k in 0..prep.n {
        expected.push((x.clone(), s.clone()));
        if k + 1 < prep.n {
            let (mut xn, mut sn) = (vec![0.0; 2], vec![0.0; 2 * n]);
            sens.step_sensitivity(&c, &prep.inputs, k, &x, &s, &mut xn, &mut sn);
            (x, s) = (xn, sn);
        }
    }
    for x0_sensitivity in [false, true] {
        let options = greybox::simulate::SimOptions { x0_sensitivity, ..Default::default() };
        let mut seen = 0;
        greybox::simulate::simulate_blocks(&m, &prep, &theta, &options, true, |b| {
            for t in 0..b.len {
                let (x, s) = &expected[b.k0 + t];
                for i in 0..2 {
                    assert_eq!(b.y(i)[t].to_bits(), x[i].to_bits(), "ŷ_{i} at {}", b.k0 + t);
                    for j in 0..n {
                        assert_eq!(
                            b.dy(i, j)[t].to_bits(),
                            s[i * n + j].to_bits(),
                            "∂ŷ_{i}/∂θ_{j} at {}",
                            b.k0 + t
                        );
                    }
                    for mm in 0..b.n_x0() {
                        // ∂ŷ/∂x₀: the identity at the start, then nothing (every period restarts).
                        let want = if b.k0 + t == 0 { f64::from(u8::from(i == mm)) } else { 0.0 };
                        assert!((b.dy0(i, mm)[t] - want).abs() < 1e-9, "∂ŷ_{i}/∂x₀_{mm} at {}", b.k0 + t);
                    }
                }
            }
            seen += b.len;
            Ok(())
        })
        .unwrap();
        assert_eq!(seen, prep.n);
    }
}

/// The loop search's residuals without the margins are the sign margins' residuals to the
/// bit (one step a period where the margins take two).
#[test]
fn the_one_step_residuals_are_the_sign_margins_residuals() {
    let (e, m, theta) = short_log_at_truth();
    let inputs = m.prepare(&e).unwrap();
    let margins = m.sign_margins(&theta, &inputs).unwrap();
    let residuals = m.one_step_residuals(&theta, &inputs).unwrap();
    assert_eq!(residuals.len(), margins.len());
    assert!(residuals.iter().skip(1).any(|r| *r > 0.0));
    for (k, (r, s)) in residuals.iter().zip(&margins).enumerate() {
        assert_eq!(r.to_bits(), s.residual.to_bits(), "sample {k}");
    }
}

/// The PWM fit recovers the motor and the inverter from the reference voltage of the
/// simulator's switching inverter, to the tolerances (R_s, L_s 0.3 %, K_e 0.05 %,
/// t_d 5 %, u_th 10 %).
#[test]
fn the_pwm_fit_recovers_the_motor_and_the_inverter() {
    let (e, cfg) = pwm_log("exp3", 2.0, 3e-6, 1.0, 0.0);
    let fit = pwm_fit(&e, &cfg, PwmInverter::default());
    let want = truth(&cfg, 3e-6, 1.0);
    let names = ["r_s", "l_s", "k_e", "t_d", "u_th"];
    for (n, (w, tol)) in names.iter().zip(want.iter().zip([3e-3, 3e-3, 5e-4, 0.05, 0.1])) {
        let err = rel(fit.parameter(n).unwrap().value, *w);
        eprintln!("{n}: relative error {err:.2e}");
        assert!(err < tol, "{n}: {err:e}");
    }
    // The fit's comparison (the plot, --residuals) is the PWM model's one-step prediction,
    // not the averaged model's simulation: its residual is the fit's.
    let c = &fit.comparisons(std::slice::from_ref(&e)).unwrap()[0];
    let counted: Vec<f64> = (0..c.y.len())
        .filter(|i| c.counted.is_empty() || c.counted[i / c.outputs.len()])
        .map(|i| c.y[i] - c.y_hat[i])
        .collect();
    let rms = (counted.iter().map(|r| r * r).sum::<f64>() / counted.len() as f64).sqrt();
    eprintln!("comparison residual rms {rms:.2e} A");
    assert!(rms < 1e-2, "{rms:e}");
}

/// The ripple near the currents' zero crossings: on motulator's PWM log with the lower
/// drop (shared; currents of a few amperes crossing zero often) the averaged dead-time
/// model with its automatic mask misses R_s by more than 1 %, the switching-resolved one
/// is within 0.3 % (both from the reference voltage, without the setup checks).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn the_ripple_is_in_the_pwm_model_and_not_in_the_averaged_one() {
    crate::common::require_shared!();
    let e = shared_log("servo_spm_pwm_deadtime_lowdrop");
    let base =
        PmsmFitOptions { input: VoltageInput::REFERENCE, skip_setup_checks: true, ..PmsmFitOptions::new(4) };
    let averaged = PmsmFitOptions {
        hold: HoldChoice::Stator,
        inverter: Some(InverterModel { mask: Some(DeadTimeMask::Auto), ..Default::default() }),
        ..base.clone()
    };
    let r_avg = fit_pmsm(std::slice::from_ref(&e), &averaged).unwrap().parameter("r_s").unwrap().value;
    let pwm = PmsmFitOptions { pwm: Some(PwmInverter { u_dc: Some(400.0), ..Default::default() }), ..base };
    let r_pwm = fit_pmsm(&[e], &pwm).unwrap().parameter("r_s").unwrap().value;
    eprintln!(
        "r_s: averaged {:+.3} %, PWM {:+.3} %",
        100.0 * (r_avg / 0.9 - 1.0),
        100.0 * (r_pwm / 0.9 - 1.0)
    );
    assert!(rel(r_avg, 0.9) > 0.01, "the averaged model is within 1 %: {r_avg}");
    assert!(rel(r_pwm, 0.9) < 3e-3, "{r_pwm}");
}

/// motulator's PWM logs (shared): with the true parameters the step predicts the next
/// current to a few µA in the median period (the rest: the logs' 12-bit duty-ratio counter
/// and their seven digits), where the averaged reference is off by about a milliampere.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn the_pwm_step_predicts_motulators_pwm_logs() {
    crate::common::require_shared!();
    let e = shared_log("servo_spm_pwm_deadtime_idinj");
    let setup = greybox::pmsm::PmsmSetup {
        input: VoltageInput::REFERENCE,
        ..greybox::pmsm::PmsmSetup::new(4, VoltageHold::Stator)
    };
    let theta = [0.9, 4.5e-3, 0.538_887_743_412_299_2, 3e-6, 0.8];
    let median = |levels: Option<u32>| {
        let inv = PwmInverter { u_dc: Some(560.0), levels, ..Default::default() };
        let mut err = one_step_errors(&PmsmPwm::new(setup, MotorKind::Spm, inv), &e, &theta, 2);
        err.sort_by(f64::total_cmp);
        err[err.len() / 2]
    };
    let (counter, continuous) = (median(Some(4096)), median(None));
    eprintln!("median one-step error: {counter:.2e} A with the counter, {continuous:.2e} A without");
    assert!(counter < 2e-5, "{counter:e}");
    assert!(continuous < 3e-3, "{continuous:e}");
}

/// The controller's frame: motulator's sensored controller transforms its reference with
/// its observer's angle, a phase-locked loop on the encoder (`k_θ = 2 α`, `k_ω = α²`, α the
/// matched pole of 2π·400 rad/s at 100 µs, 2223.9 rad/s). With that frame and the log's
/// 12-bit counter the step predicts the shared log at the true parameters to rounding in
/// 99 % of its periods; with the logged angle, a period in ten is off by a milliampere.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn the_controller_frame_is_the_loops() {
    crate::common::require_shared!();
    let e = shared_log("servo_spm_pwm_deadtime_idinj");
    let theta = [0.9, 4.5e-3, 0.538_887_743_412_299_2, 3e-6, 0.8];
    let alpha = (1.0 - (-std::f64::consts::TAU * 400.0 * 1e-4_f64).exp()) / 1e-4;
    let quantile = |speed_pll: Option<f64>, q: f64| {
        let setup = greybox::pmsm::PmsmSetup {
            input: VoltageInput::Reference { delay: 1, advance: 1.5, speed_pll },
            ..greybox::pmsm::PmsmSetup::new(4, VoltageHold::Stator)
        };
        let inv = PwmInverter { u_dc: Some(560.0), levels: Some(4096), ..Default::default() };
        let mut err = one_step_errors(&PmsmPwm::new(setup, MotorKind::Spm, inv), &e, &theta, 2);
        err.sort_by(f64::total_cmp);
        err[(q * err.len() as f64) as usize]
    };
    let (frame, logged) = (quantile(Some(alpha), 0.99), quantile(None, 0.9));
    eprintln!(
        "one-step error: 99th percentile {frame:.2e} A in the loop's frame, 90th {logged:.2e} A logged"
    );
    assert!(frame < 1e-4, "{frame:e}");
    assert!(logged > 1e-3, "{logged:e}");
}

/// Noise on the measured current: the unmasked fit's leg-state width holds the noise (a
/// one-step prediction from a noisy current turns its signs near zero as a wide leg state
/// would), and held in the masked fit its atan tail pulled r_s 2.5 % low on motulator's
/// noisy logs. The masked fit of the sign on the same samples has the lower loss on a log
/// whose inverter switches hard (the simulator's), and the motor's parameters are within
/// their intervals at 0.01 A (at 0.05 A on this low-current log the restart from the noisy
/// current biased r_s by 12 %, errors in the variables; with the criterion compensated,
/// docs/options.md step 6, r_s is within 0.01 %, but u_th goes to its bound 0 and the fit
/// is untrusted).
#[test]
fn a_noisy_current_leaves_the_leg_state_the_sign() {
    let cfg = scenario("exp3", SPM_MOTOR).unwrap();
    let mut inverter = cfg.inverter.clone();
    inverter.pwm = Some(PwmPlant { t_d: 3e-6, u_th: 1.0, i_w: 0.0, levels: 0 });
    let sensors = greybox::drive::Sensors { current_noise: 0.01, ..Default::default() };
    let cfg = DriveConfig { inverter, sensors, duration: 2.0, seed: 5, ..cfg };
    let e = simulate_drive(&cfg).unwrap().experiment;
    let fit = pwm_fit(&e, &cfg, PwmInverter { estimate_i_w: true, ..Default::default() });
    let note =
        fit.pmsm_notes.iter().find(|n| n.contains("leg state on the masked")).expect("the leg-state choice");
    eprintln!("{note}");
    assert!(fit.pwm.is_some_and(|p| !p.estimate_i_w && p.i_w.is_none()), "{note}");
    assert!(fit.parameter("i_w").is_none());
    for (n, w) in ["r_s", "l_s", "k_e"].iter().zip(truth(&cfg, 3e-6, 1.0)) {
        let p = fit.parameter(n).unwrap();
        let z = (p.value - w) / p.std_error;
        eprintln!("{n}: relative error {:.2e}, z {z:.2}", rel(p.value, w));
        assert!(z.abs() < 3.0, "{n}: z {z}");
    }
}

/// The command line refuses a PWM model it cannot run, naming the flag: without the
/// reference voltage, without the DC link, at a carrier the sample time does not allow, and
/// a PWM flag without `--inverter pwm`; nothing is written.
#[test]
fn the_command_line_names_the_missing_pwm_flag() {
    let dir = std::env::temp_dir().join(format!("greybox_pwm_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (e, _) = pwm_log("exp3", 0.3, 2e-6, 1.0, 0.0);
    let log = dir.join("pwm.csv");
    greybox::data::write_csv(&log, &e, "t").unwrap();
    let json = dir.join("out.json");
    let run = |extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_greybox"))
            .args(["fit", log.to_str().unwrap(), "-p", "4", "--json", json.to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap();
        (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    for (extra, names) in [
        (&["--inverter", "pwm", "--u-dc", "320"][..], "--voltage reference"),
        (&["--voltage", "reference", "--inverter", "pwm"][..], "--u-dc"),
        (
            &["--voltage", "reference", "--inverter", "pwm", "--u-dc", "320", "--carrier-hz", "8000"][..],
            "--carrier-hz",
        ),
        (&["--voltage", "reference", "--pwm-levels", "4096"][..], "--inverter pwm"),
    ] {
        let (code, err) = run(extra);
        assert_ne!(code, Some(0), "{extra:?}");
        assert!(err.contains(names), "{extra:?}: {err}");
        assert!(!json.exists(), "{extra:?} wrote a report");
    }
    std::fs::remove_dir_all(&dir).ok();
}
