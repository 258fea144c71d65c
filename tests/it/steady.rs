//! The steady-state fit of slow logs (issue 32, part 2): a drive-simulator log at 10 kHz
//! with current and voltage noise, decimated to 100 Hz and 2 Hz by point samples (a host
//! logger reads the drive's latest values; it does not average), fitted by
//! [`steady_state`] and by [`fit_pmsm`]'s automatic choice; the plain regression over all
//! samples and the dynamic fit on the same log for contrast; a fast log with its time column
//! in ms named as such; per-log R_s; the command line; bad input.

use crate::common::rel;
use greybox::drive::{DriveConfig, IPM_MOTOR, SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{
    Dynamics, MotorKind, MotorParameters, PmsmFitOptions, SteadyOptions, fit_pmsm, steady_state,
};
use greybox::{Channel, Experiment};

/// exp3's motor and controller, with long holds (3 s at ±30, 100, 190, 280 rad/s, 1 s at
/// rest), a constant load of 20 % of the peak torque (load current at every speed; exp3's
/// gravity arm would make i_q swing with the angle) and −0.3 i_max on the d axis through
/// the holds at 100 and 190 rad/s (L_d); current noise 0.02 A, voltage noise 0.5 V. 31.3 s.
fn slow_drive(motor: MotorParameters) -> (Experiment, greybox::drive::Truth) {
    slow_drive_seed(motor, 1)
}

/// [`slow_drive`] with noise seed `seed`.
fn slow_drive_seed(motor: MotorParameters, seed: u64) -> (Experiment, greybox::drive::Truth) {
    slow_drive_with(motor, seed, true)
}

/// [`slow_drive`] with noise seed `seed`, with or without the sensor noise.
fn slow_drive_with(motor: MotorParameters, seed: u64, noisy: bool) -> (Experiment, greybox::drive::Truth) {
    let log = simulate_drive(&slow_config(motor, seed, noisy)).unwrap();
    (log.experiment, log.truth)
}

/// The drive of [`slow_drive_with`].
fn slow_config(motor: MotorParameters, seed: u64, noisy: bool) -> DriveConfig {
    let base = scenario("exp3", motor).unwrap();
    let c = base.control.clone();
    let t_max = motor.k_t() * c.i_max;
    let reference = greybox::drive::Profile::back_and_forth(0.1, &[30.0, 100.0, 190.0, 280.0], 0.2, 3.0, 1.0);
    // Level j starts at 0.1 + 7.8 j; its holds are [0.3, 3.3] and [3.7, 6.7] after that.
    let mut i_d = vec![(0.0, 0.0)];
    for j in [1.0, 2.0] {
        let s = 0.1 + 7.8 * j;
        i_d.extend([(s + 0.3, 0.0), (s + 0.3, -0.3 * c.i_max), (s + 3.3, -0.3 * c.i_max), (s + 3.3, 0.0)]);
    }
    DriveConfig {
        control: greybox::drive::Control { reference, i_d: greybox::drive::Profile(i_d), ..c },
        mechanics: greybox::drive::Mechanics {
            gravity: 0.0,
            load: greybox::drive::Profile::constant(0.2 * t_max),
            ..base.mechanics.clone()
        },
        sensors: if noisy {
            greybox::drive::Sensors { current_noise: 0.02, voltage_noise: 0.5, ..Default::default() }
        } else {
            greybox::drive::Sensors::default()
        },
        duration: 31.3,
        seed,
        ..base
    }
}

/// The steady-state options with the drive's control period (the simulator's 1e-4 s, a
/// setting of the drive a user knows), unless `STEADY_CONTINUOUS` is set.
fn options() -> SteadyOptions {
    let control_period = std::env::var("STEADY_CONTINUOUS").is_err().then_some(1e-4);
    SteadyOptions { control_period, ..Default::default() }
}

fn kind(t: &greybox::drive::Truth) -> MotorKind {
    if t.start.salient() { MotorKind::Ipm } else { MotorKind::Spm }
}

fn truth_of(t: &greybox::drive::Truth) -> [(&'static str, f64); 5] {
    [("r_s", t.start.r_s), ("l_s", t.start.l_q), ("l_d", t.start.l_d), ("l_q", t.start.l_q), ("k_e", t.k_e)]
}

/// 100 Hz and 2 Hz on both motors, with the drive's control period: R_s and K_e within
/// their 95 % intervals, and at 100 Hz within 0.5 % and 0.05 %; the inductances within
/// theirs unless the fit notes them not identifiable. Measured (seed 1): 100 Hz SPM R_s
/// +0.078 %, K_e −0.023 %; IPM R_s +0.073 %, K_e −0.027 %; all within 0.9 half widths.
/// `STEADY_REPORT=1` prints only.
#[test]
fn steady_state_recovers_slow_logs() {
    for motor in [SPM_MOTOR, IPM_MOTOR] {
        let (fast, t) = slow_drive(motor);
        for (factor, tight) in [(100, true), (5000, false)] {
            let e = fast.decimate(factor).unwrap();
            let est = steady_state(std::slice::from_ref(&e), t.start.n_p, kind(&t), &options()).unwrap();
            eprintln!("{} at {} Hz:\n{est}", kind(&t).model_name(), 1.0 / e.h());
            for (name, v) in truth_of(&t) {
                let Some((x, ci)) = est.interval(name) else { continue };
                eprintln!(
                    "  {name}: {x:.6e} truth {v:.6e} rel {:+.3e} ({:.2} half widths)",
                    x / v - 1.0,
                    (x - v).abs() / ci
                );
                let noted = est.notes.iter().any(|n| n.starts_with(name));
                if std::env::var("STEADY_REPORT").is_err() && !noted {
                    assert!((x - v).abs() <= ci, "{name} at {factor}: {x} ± {ci} vs {v}");
                }
            }
            if tight && std::env::var("STEADY_REPORT").is_err() {
                assert!(rel(est.value("r_s").unwrap(), t.start.r_s).abs() < 5e-3);
                assert!(rel(est.value("k_e").unwrap(), t.k_e).abs() < 5e-4);
            }
        }
    }
}

/// The cause of the continuous equations' K_e bias, noise-free at 100 Hz: the point-sampled
/// current against the period-mean voltage reads the back-EMF low by `(ω_e h_c)²/12`
/// (1.05e-3 at the top speed). By default the fit estimates that term (the nuisance `h_c2`,
/// the control period squared: the drive simulator's 1e-4 s recovered within 2 %); the
/// exact periodic steady state at a given control period removes it as well, both to 1e-5.
#[test]
fn control_period_removes_the_point_sample_bias() {
    let (clean, t) = slow_drive_with(SPM_MOTOR, 1, false);
    let e = clean.decimate(100).unwrap();
    let one = std::slice::from_ref(&e);
    let cont = steady_state(one, t.start.n_p, MotorKind::Spm, &SteadyOptions::default()).unwrap();
    let exact = steady_state(
        one,
        t.start.n_p,
        MotorKind::Spm,
        &SteadyOptions { control_period: Some(1e-4), ..Default::default() },
    )
    .unwrap();
    let signed = |x: f64| x / t.k_e - 1.0;
    let (kc, kx) = (signed(cont.value("k_e").unwrap()), signed(exact.value("k_e").unwrap()));
    let h_c = cont.value(greybox::pmsm::PERIOD_TERM).unwrap().sqrt();
    eprintln!(
        "noise-free 100 Hz: k_e with h_c estimated {kc:+.3e} (h_c {h_c:.4e} s), at the control period {kx:+.3e}"
    );
    assert!((h_c / 1e-4 - 1.0).abs() < 0.02, "h_c {h_c:e}");
    assert!(kc.abs() < 1e-5, "k_e with the period estimated {kc:+.3e}");
    assert!(kx.abs() < 1e-5, "exact k_e {kx:+.3e}");
    assert!(exact.value(greybox::pmsm::PERIOD_TERM).is_none());
    assert!(exact.iterations > 1 && cont.iterations > 1);
}

/// For contrast on the 100 Hz log: the plain least squares over all samples (transients
/// and noise in the regressors), the dynamic fit refused (the rotor turns 11 electrical rad
/// per sample) and, forced, untrusted; the automatic choice fits the steady-state equations
/// with a note saying why.
#[test]
fn automatic_choice_plain_regression_and_dynamic_fit_on_the_100_hz_log() {
    let (fast, t) = slow_drive(SPM_MOTOR);
    let e = fast.decimate(100).unwrap();
    let one = std::slice::from_ref(&e);
    let ls = greybox::pmsm::least_squares(one, t.start.n_p, MotorKind::Spm).unwrap();
    eprintln!(
        "plain LS at 100 Hz: r_s {:+.3e}, k_e {:+.3e}",
        rel(ls.value("r_s").unwrap(), t.start.r_s),
        rel(ls.value("k_e").unwrap(), t.k_e)
    );
    let auto = fit_pmsm(one, &PmsmFitOptions::new(t.start.n_p)).unwrap();
    assert_eq!(auto.report.model, "pmsm_spm_steady");
    assert!(auto.pmsm_notes.iter().any(|n| n.contains("steady-state model chosen")), "{:?}", auto.pmsm_notes);
    // 32 s of 100 Hz telemetry with current and voltage noise tell r_s to ±0.95 % at three
    // standard errors: short of the default accuracy (0.5 %), the only reason it is untrusted.
    let untrusted: Vec<&str> =
        auto.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.as_str()).collect();
    assert_eq!(untrusted, ["imprecise"], "{:?}", auto.warnings);
    let stated = PmsmFitOptions { precision: Some(Vec::new()), ..PmsmFitOptions::new(t.start.n_p) };
    let auto = fit_pmsm(one, &stated).unwrap();
    assert!(auto.trusted(), "{:?}", auto.warnings);
    for (name, truth) in [("r_s", t.start.r_s), ("k_e", t.k_e)] {
        let p = auto.parameter(name).unwrap();
        assert!((p.value - truth).abs() <= 3.0 * p.std_error, "{name} {} against {truth}", p.value);
    }
    let dynamic = PmsmFitOptions { dynamics: Dynamics::Dynamic, ..PmsmFitOptions::new(t.start.n_p) };
    let refused = fit_pmsm(one, &dynamic).unwrap_err().to_string();
    assert!(refused.contains("sample time"), "{refused}");
    let forced = fit_pmsm(one, &PmsmFitOptions { force: true, ..dynamic }).unwrap();
    eprintln!("dynamic fit at 100 Hz, forced:\n{forced}");
    assert!(!forced.trusted(), "the forced dynamic fit of a 100 Hz log must not pass as trusted");
}

/// A 10 kHz log whose time column was in ms, read as s (h = 0.1 s): named as such by the
/// angle (when logged) and by the currents' dynamics (without the angle), not fitted as
/// steady state, whether the equations were chosen or asked for.
#[test]
fn fast_log_in_milliseconds_is_named_not_fitted_as_steady() {
    let (fast, t) = slow_drive(SPM_MOTOR);
    let part = fast.slice(0..60_000).unwrap();
    let with_angle = Experiment::try_new("ms", part.h() * 1e3, part.channels().to_vec()).unwrap();
    let without: Vec<Channel> = part.channels().iter().filter(|c| c.name != "theta_m").cloned().collect();
    let without = Experiment::try_new("ms", part.h() * 1e3, without).unwrap();
    for e in [with_angle, without] {
        for dynamics in [Dynamics::Auto, Dynamics::Steady] {
            let o = PmsmFitOptions { dynamics, ..PmsmFitOptions::new(t.start.n_p) };
            let err = match fit_pmsm(std::slice::from_ref(&e), &o) {
                Ok(f) => {
                    panic!("{} channels, {dynamics:?}: fitted as {}", e.channels().len(), f.report.model)
                }
                Err(err) => err.to_string(),
            };
            assert!(err.contains("milliseconds") && err.contains("--time-unit ms"), "{err}");
        }
    }
}

/// Per-log R_s in a joint steady-state fit of a cold and a warm log (R_s 1.2 and 1.32 Ω,
/// the winding 25 K warmer), L and K_e shared: each R_s within 3 standard errors of its
/// truth and the temperature rise within 3 of its own (one seed: an honest interval fails
/// this with probability 0.3 %; the intervals' coverage is measured by Monte Carlo in
/// `examples/steady_coverage.rs`, 0.95 for R_s), the winding temperatures derived per log.
#[test]
fn per_log_resistance_and_winding_temperature() {
    let warm = MotorParameters { r_s: 1.32, ..SPM_MOTOR };
    let (cold_log, t) = slow_drive_seed(SPM_MOTOR, 2);
    let (warm_log, tw) = slow_drive_seed(warm, 3);
    let logs = [cold_log.decimate(100).unwrap(), warm_log.decimate(100).unwrap()];
    let logs = [
        Experiment::try_new("cold", logs[0].h(), logs[0].channels().to_vec()).unwrap(),
        Experiment::try_new("warm", logs[1].h(), logs[1].channels().to_vec()).unwrap(),
    ];
    let o = PmsmFitOptions {
        dynamics: Dynamics::Steady,
        control_period: Some(1e-4),
        thermal: Some(greybox::pmsm::ThermalReference::try_new(20.0, Some(1.2), None).unwrap()),
        pem: greybox::estimate::PemOptions { per_experiment: vec!["r_s".into()], ..Default::default() },
        ..PmsmFitOptions::new(t.start.n_p)
    };
    let fit = fit_pmsm(&logs, &o).unwrap();
    eprintln!("{fit}");
    let r: Vec<_> = fit.parameters.iter().filter(|p| p.name == "r_s").collect();
    assert_eq!(r.len(), 2);
    for (p, truth) in r.iter().zip([t.start.r_s, tw.start.r_s]) {
        assert!((p.value - truth).abs() <= 3.0 * p.std_error, "{} ± {} vs {truth}", p.value, p.std_error);
    }
    let temps: Vec<_> = fit.derived.iter().filter(|d| d.name == "t_winding").collect();
    assert_eq!(temps.len(), 2);
    let rise = temps[1].value - temps[0].value;
    let se = (temps[0].std_error.powi(2) + temps[1].std_error.powi(2)).sqrt();
    let true_rise = (1.32 / 1.2 - 1.0) / greybox::pmsm::ALPHA_COPPER;
    assert!((rise - true_rise).abs() <= 3.0 * se, "rise {rise} ± {se} vs {true_rise}");
}

/// Bad input: too few steady samples, bad options, options the equations do not take.
#[test]
fn steady_state_refuses_bad_input() {
    let (fast, t) = slow_drive(SPM_MOTOR);
    let e = fast.decimate(100).unwrap();
    let one = std::slice::from_ref(&e);
    let bad = SteadyOptions { steady_sigmas: -1.0, ..Default::default() };
    assert!(steady_state(one, t.start.n_p, MotorKind::Spm, &bad).is_err());
    let bad = SteadyOptions { control_period: Some(0.0), ..Default::default() };
    assert!(
        steady_state(one, t.start.n_p, MotorKind::Spm, &bad)
            .unwrap_err()
            .to_string()
            .contains("control_period")
    );
    for derivative_half_width in [0, 5] {
        let bad = SteadyOptions { derivative_half_width, ..Default::default() };
        let err = steady_state(one, t.start.n_p, MotorKind::Spm, &bad).unwrap_err().to_string();
        assert!(err.contains("derivative_half_width"), "{err}");
    }
    let bad = SteadyOptions { per_experiment: vec!["l_d".into()], ..Default::default() };
    assert!(steady_state(one, t.start.n_p, MotorKind::Spm, &bad).unwrap_err().to_string().contains("l_d"));
    assert!(steady_state(one, 0, MotorKind::Spm, &SteadyOptions::default()).is_err());
    let short = e.slice(0..3).unwrap();
    assert!(steady_state(&[short], t.start.n_p, MotorKind::Spm, &SteadyOptions::default()).is_err());
    let o = PmsmFitOptions {
        dynamics: Dynamics::Steady,
        start: Some(vec![1.0, 5e-3, 0.5]),
        ..PmsmFitOptions::new(t.start.n_p)
    };
    let err = fit_pmsm(one, &o).unwrap_err().to_string();
    assert!(err.contains("a start"), "{err}");
}

/// A control period that is not positive is refused whichever equations the log gets (a
/// dynamic fit would otherwise ignore it silently).
#[test]
fn a_bad_control_period_is_refused_for_any_log() {
    let log = greybox::pmsm::read_log(
        concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"),
        &Default::default(),
    )
    .unwrap();
    let o = PmsmFitOptions { control_period: Some(-1e-4), ..PmsmFitOptions::new(4) };
    let err = fit_pmsm(&[log], &o).unwrap_err().to_string();
    assert!(err.contains("control_period"), "{err}");
}

/// Every 20th row of the noise-free 10 kHz log (500 Hz telemetry: point samples of a voltage
/// that moves within the 2 ms) fitted by the dynamic model had r_s 3 % low with exit 0 on
/// the shared logs: the voltage-sampling check sees the trapezoidal voltage fit better than
/// the held one, and the automatic choice takes the steady-state equations (r_s within 0.5 %,
/// k_e within 0.05 %, trusted); the dynamic model forced is untrusted
/// (`point_sampled_voltage`); `--method iv` keeps the steady-state fit (itself instrumental
/// variables). A drive controlled at 1 kHz, whose logged voltage is held over
/// each period, keeps the dynamic model and no such warning.
#[test]
fn point_sampled_telemetry_is_fitted_by_the_steady_state_equations() {
    let (fast, t) = slow_drive_with(SPM_MOTOR, 1, false);
    let e = fast.decimate(20).unwrap();
    let one = std::slice::from_ref(&e);
    let auto = fit_pmsm(one, &PmsmFitOptions::new(t.start.n_p)).unwrap();
    eprintln!("every 20th row: {:?}", auto.pmsm_notes);
    assert_eq!(auto.report.model, "pmsm_spm_steady");
    assert!(auto.pmsm_notes.iter().any(|n| n.contains("point samples")), "{:?}", auto.pmsm_notes);
    assert!(auto.trusted(), "{:?}", auto.warnings);
    for (name, truth, within) in [("r_s", t.start.r_s, 5e-3), ("k_e", t.k_e, 5e-4)] {
        let p = auto.parameter(name).unwrap();
        eprintln!("every 20th row: {name} {:+.3e}", rel(p.value, truth));
        assert!(rel(p.value, truth).abs() < within, "{name}");
    }
    // Instrumental variables asked for: the steady-state equations are fitted by them already
    // (the dynamic recursion from their estimate gave l_s +170 % with exit 0).
    let iv = greybox::pmsm::fit_pmsm_iv(one, &PmsmFitOptions::new(t.start.n_p)).unwrap();
    assert_eq!(iv.report.model, "pmsm_spm_steady");
    assert_eq!(iv.parameter("l_s").unwrap().value, auto.parameter("l_s").unwrap().value);
    let forced = fit_pmsm(one, &PmsmFitOptions { force: true, ..PmsmFitOptions::new(t.start.n_p) }).unwrap();
    assert_eq!(forced.report.model, "pmsm_spm");
    assert!(
        forced.warnings.iter().any(|w| w.code == "point_sampled_voltage" && w.untrusted),
        "{:?}",
        forced.warnings
    );
    let base = slow_config(SPM_MOTOR, 1, false);
    let held = DriveConfig {
        control: greybox::drive::Control {
            h: 1e-3,
            alpha_c: 2.0 * std::f64::consts::PI * 50.0,
            ..base.control.clone()
        },
        ..base
    };
    let log = simulate_drive(&held).unwrap();
    let one = std::slice::from_ref(&log.experiment);
    let fit = fit_pmsm(one, &PmsmFitOptions::new(t.start.n_p)).unwrap();
    eprintln!("held at 1 kHz: {:?} {:?}", fit.report.model, fit.warnings);
    assert_eq!(fit.report.model, "pmsm_spm");
    assert!(!fit.warnings.iter().any(|w| w.code == "point_sampled_voltage"), "{:?}", fit.warnings);
    let p = fit.parameter("r_s").unwrap();
    assert!(rel(p.value, t.start.r_s).abs() < 1e-3, "held 1 kHz r_s {:+.3e}", rel(p.value, t.start.r_s));
}

/// A given control period on logs whose first estimate is not physical (here the 100 Hz log
/// with `1.5 r_s i` taken off both voltages: the data of a resistance of `−r_s/2`): the
/// exact equations cannot be formed there, and the fit reports the equations without the
/// period, says so, and is untrusted for the estimate (`non_physical`), as without
/// `--control-period`. Before, the fit ended with an error (exit 1, no report) naming an
/// `r_s` the user never gave (found on a set-aside gym-electric-motor IPM log, every 160th
/// row).
#[test]
fn a_control_period_at_a_non_physical_estimate_is_reported_not_an_error() {
    let (fast, t) = slow_drive_with(SPM_MOTOR, 1, false);
    let e = fast.decimate(100).unwrap();
    let minus = |v: &str, i: &str| {
        let (u, i) = (e.get(v).unwrap(), e.get(i).unwrap());
        let values = u.values.iter().zip(i.values.iter()).map(|(u, i)| u - 1.5 * t.start.r_s * i).collect();
        Channel::new(v, &u.unit, values)
    };
    let (ud, uq) = (minus("ud", "id"), minus("uq", "iq"));
    let e = e.with_channel(ud).unwrap().with_channel(uq).unwrap();
    let one = std::slice::from_ref(&e);
    let given = SteadyOptions { control_period: Some(1e-4), ..Default::default() };
    let est = steady_state(one, t.start.n_p, MotorKind::Spm, &given).unwrap();
    let r_s = est.value("r_s").unwrap();
    assert!(r_s < 0.0, "r_s {r_s}");
    assert!(est.control_period.is_none());
    assert!(est.notes.iter().any(|n| n.contains("is not applied")), "{:?}", est.notes);
    let options = PmsmFitOptions {
        dynamics: Dynamics::Steady,
        control_period: Some(1e-4),
        ..PmsmFitOptions::new(t.start.n_p)
    };
    let fit = fit_pmsm(one, &options).unwrap();
    assert!(fit.report.warnings.iter().any(|w| w.code == "non_physical" && w.untrusted));
}

/// A corrupt speed cell (one row of the README's sample log at 999 999 rad/s) makes the
/// automatic choice take the steady-state equations (the rotor would turn half a turn in a
/// sample there); with options those equations do not take (bounds), the error says the
/// choice was automatic, names the row and asks to mend the cell: before, it read
/// "invalid option `--model`" to a user who never gave `--model`.
#[test]
fn an_automatic_steady_choice_names_the_row_behind_it() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz");
    let e = greybox::pmsm::read_log(path, &Default::default()).unwrap();
    let w = e.get("w_m").unwrap();
    let mut values = w.values.to_vec();
    values[10_000] = 999_999.0;
    let spiked = Channel::new("w_m", &w.unit, values);
    let e = e.with_channel(spiked).unwrap();
    let options = PmsmFitOptions { bounds: vec![("k_e".into(), 0.1, 2.0)], ..PmsmFitOptions::new(4) };
    let err = fit_pmsm(std::slice::from_ref(&e), &options).unwrap_err().to_string();
    for says in ["chosen automatically", "row 10000", "corrupt cell", "bounds", "--force"] {
        assert!(err.contains(says), "{says}: {err}");
    }
}
