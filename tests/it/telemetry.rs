//! Slow telemetry cut from drive cycles (issue 43): every 40th and 160th row (250 Hz and
//! 62.5 Hz) of the shared 10 kHz logs of moves, whose plateaus are short and whose currents
//! drift along ramps and a varying load. The automatic choice fits the steady-state
//! equations (with the currents' drift and the control period's effect); before, every 40th
//! row gave R_s +0.47 % at |z| 19 and K_e −0.077 % at |z| 63 with exit 0. An IPM log fitted
//! with the SPM equations is untrusted (`salient`), and right with the IPM ones.

use crate::common::{load, rel};
use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{MotorKind, PmsmFitOptions, fit_pmsm};

/// R_s within 0.5 % and K_e within 0.05 % (issue 43), trusted; on the noisy log both within
/// 3 standard errors as well (the noise-free log's within 5e-5: the data's 7 digits). The
/// noisy log's every 160th row tells R_s and K_e to ±0.54 % and ±0.088 % only (three
/// standard errors): untrusted (`imprecise`), honest all the same.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn drive_cycle_telemetry_is_fitted_by_the_steady_state_equations() {
    for (stem, noisy) in [("servo_spm_moves", false), ("servo_spm_moves_idinj_noisy", true)] {
        let (fast, t) = load(stem);
        for every in [40, 160] {
            let precise = !(noisy && every == 160);
            let e = fast.decimate(every).unwrap();
            let fit = fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions::new(t.n_p)).unwrap();
            assert_eq!(fit.report.model, "pmsm_spm_steady");
            for (name, truth, within) in [("r_s", t.r_s, 5e-3), ("k_e", t.k_e, 5e-4)] {
                let p = fit.parameter(name).unwrap();
                let z = (p.value - truth) / p.std_error;
                eprintln!("{stem} every {every}th row: {name} {:+.3e} (z {z:+.1})", rel(p.value, truth));
                assert!(rel(p.value, truth).abs() < if noisy { within } else { 5e-5 }, "{name}");
                if noisy {
                    assert!(z.abs() <= 3.0, "{stem} {every}: {name} z {z}");
                }
            }
            let untrusted: Vec<&str> =
                fit.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.as_str()).collect();
            let expected: &[&str] = if precise { &[] } else { &["imprecise"] };
            assert_eq!(untrusted, expected, "{stem} every {every}th row: {:?}", fit.warnings);
        }
    }
}

/// Every 80th row of the IPM log of moves: the SPM equations untrusted (`salient`), the IPM
/// ones trusted and right.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn salient_telemetry_is_named_under_the_spm_equations() {
    let (fast, t) = load("ipm_moves_idinj");
    let e = fast.decimate(80).unwrap();
    let one = std::slice::from_ref(&e);
    let spm = fit_pmsm(one, &PmsmFitOptions::new(t.n_p)).unwrap();
    assert!(spm.warnings.iter().any(|w| w.code == "salient" && w.untrusted), "{:?}", spm.warnings);
    assert!(!spm.trusted());
    let ipm = fit_pmsm(one, &PmsmFitOptions { model: MotorKind::Ipm, ..PmsmFitOptions::new(t.n_p) }).unwrap();
    assert!(ipm.trusted(), "{:?}", ipm.warnings);
    for (name, truth) in [("r_s", t.r_s), ("l_d", t.l_d), ("l_q", t.l_q), ("k_e", t.k_e)] {
        let p = ipm.parameter(name).unwrap();
        eprintln!("ipm every 80th row: {name} {:+.3e}", rel(p.value, truth));
        assert!(rel(p.value, truth).abs() < 1e-3, "{name}");
    }
}

/// Every 20th row of the shared SPM logs of moves (500 Hz) and every 25th of the IPM one
/// (200 Hz): the sample time is within the dynamic model's range, but the voltage is a point
/// sample; the dynamic model had r_s 3–4 % low with exit 0 (the IPM's at |z| 25), and the
/// voltage-sampling check now sends them to the steady-state equations: R_s within 0.5 %,
/// K_e within 0.05 %, trusted; the noisy log's quarters disagree on K_e beyond their
/// standard errors (Cochran's Q below 0.05/3), whose interval the spread widens past the
/// 0.05 % target at three standard errors: untrusted (`imprecise`), honest all the same
/// (its L_s was at |z| 3.07 before).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn point_sampled_telemetry_in_the_dynamic_range_takes_the_steady_state_equations() {
    for (stem, every, kind) in [
        ("servo_spm_moves_idinj", 20, MotorKind::Spm),
        ("servo_spm_moves_idinj_noisy", 20, MotorKind::Spm),
        ("ipm_moves_idinj", 25, MotorKind::Ipm),
    ] {
        let (fast, t) = load(stem);
        let e = fast.decimate(every).unwrap();
        let fit =
            fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions { model: kind, ..PmsmFitOptions::new(t.n_p) })
                .unwrap();
        assert!(fit.report.model.ends_with("_steady"), "{stem}: {}", fit.report.model);
        assert!(fit.pmsm_notes.iter().any(|n| n.contains("point samples")), "{stem}: {:?}", fit.pmsm_notes);
        for (name, truth, within) in [("r_s", t.r_s, 5e-3), ("k_e", t.k_e, 5e-4)] {
            let p = fit.parameter(name).unwrap();
            eprintln!("{stem} every {every}th row: {name} {:+.3e}", rel(p.value, truth));
            assert!(rel(p.value, truth).abs() < within, "{stem}: {name}");
        }
        let untrusted: Vec<&str> =
            fit.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.as_str()).collect();
        let expected: &[&str] = if stem.ends_with("_noisy") { &["imprecise"] } else { &[] };
        assert_eq!(untrusted, expected, "{stem}: {:?}", fit.warnings);
    }
}

/// Every 20th row of the shared IPM log of moves (250 Hz) from its first row: the parts'
/// spread of R_s (+0.0007 … +0.0052 %, Cochran's Q at p = 3.0e-4) widens its interval
/// (R_s +0.003 % was at |z| 3.6 with exit 0 when only a Q below the verdict's 1e-3/4 did);
/// and the 2 s from 6 to 8 s, too short for the parts' check and at speeds where K_e and
/// the control period's term correlate at 0.997: the term is kept (it was neglected, K_e
/// −0.072 % at |z| 12 and R_s +0.41 % at |z| 6.5 with exit 0) and the equations' own
/// accuracy is in the intervals (L_q was at |z| 15). R_s within 0.5 % and K_e within 0.05 %
/// (issue 43), every parameter within 3 standard errors, trusted.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn noise_free_ipm_telemetry_covers_its_truth_whole_and_in_a_window() {
    let (fast, t) = load("ipm_moves_idinj");
    let e = fast.decimate(20).unwrap();
    let h = e.h();
    let window = e.slice((6.0 / h).round() as usize..(8.0 / h).round() as usize + 1).unwrap();
    for (what, log) in [("whole", e), ("6-8 s", window)] {
        let options = PmsmFitOptions { model: MotorKind::Ipm, ..PmsmFitOptions::new(t.n_p) };
        let fit = fit_pmsm(std::slice::from_ref(&log), &options).unwrap();
        assert_eq!(fit.report.model, "pmsm_ipm_steady", "{what}");
        for (name, truth, within) in
            [("r_s", t.r_s, 5e-3), ("l_d", t.l_d, 1e-3), ("l_q", t.l_q, 1e-3), ("k_e", t.k_e, 5e-4)]
        {
            let p = fit.parameter(name).unwrap();
            let z = (p.value - truth) / p.std_error;
            eprintln!("every 20th row, {what}: {name} {:+.3e} (z {z:+.2})", rel(p.value, truth));
            assert!(rel(p.value, truth).abs() < within, "{what}: {name}");
            assert!(z.abs() <= 3.0, "{what}: {name} z {z}: {:?}", fit.report.notes);
        }
        assert!(fit.trusted(), "{what}: {:?}", fit.warnings);
    }
}

/// Every 10th row of the shared noisy SPM log of moves (1 kHz): the trapezoid fits the
/// logged voltage about 1.9 times better than the held one, more than noise on a held
/// voltage can make it at this sample time (about 1.1) and less than the 2 that decides. The
/// dynamic fit had R_s −1.6 % at |z| 3.6 with exit 0; it is now untrusted
/// (`point_sampled_voltage`, the voltage may be point samples).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn telemetry_whose_voltage_may_be_point_samples_is_untrusted() {
    let (fast, t) = load("servo_spm_moves_idinj_noisy");
    let e = fast.decimate(10).unwrap();
    let fit = fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions::new(t.n_p)).unwrap();
    assert_eq!(fit.report.model, "pmsm_spm");
    let p = fit.parameter("r_s").unwrap();
    eprintln!("every 10th row: r_s {:+.3e} (z {:+.1})", rel(p.value, t.r_s), (p.value - t.r_s) / p.std_error);
    let w = fit.warnings.iter().find(|w| w.code == "point_sampled_voltage").expect("point_sampled_voltage");
    assert!(w.untrusted && w.message.contains("may be point samples"), "{w:?}");
    assert!(!fit.trusted());
}

/// Every 2nd row of the shared SPM logs of moves (5 kHz, from 10 kHz): each new interval's
/// voltage is the mean over its first half only, which the dynamic model holds over the
/// whole. The noise-free log's K_e was −0.038 % at |z| 4.5 and the noisy one's +0.127 % at
/// |z| 5.7, both with exit 0; the steady-state equations on the same rows disagree with
/// them (`steady_state_disagrees`, untrusted). The logs at their own rate stay trusted and
/// right (the noise-free one is fitted to its data's rounding and the noisy one's residuals
/// are white: the check does not run there).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn every_second_row_is_named_by_the_steady_state_equations() {
    for stem in ["servo_spm_moves_idinj", "servo_spm_moves_idinj_noisy"] {
        let (fast, t) = load(stem);
        let half = fast.decimate(2).unwrap();
        let fit = fit_pmsm(std::slice::from_ref(&half), &PmsmFitOptions::new(t.n_p)).unwrap();
        assert_eq!(fit.report.model, "pmsm_spm", "{stem}");
        let p = fit.parameter("k_e").unwrap();
        eprintln!(
            "{stem} every 2nd row: k_e {:+.3e} (z {:+.1})",
            rel(p.value, t.k_e),
            (p.value - t.k_e) / p.std_error
        );
        let w = fit.warnings.iter().find(|w| w.code == "steady_state_disagrees");
        assert!(w.is_some_and(|w| w.untrusted), "{stem}: {:?}", fit.warnings);
        assert!(!fit.trusted());
        let whole = fit_pmsm(std::slice::from_ref(&fast), &PmsmFitOptions::new(t.n_p)).unwrap();
        assert!(whole.trusted(), "{stem}: {:?}", whole.warnings);
        for (name, truth) in [("r_s", t.r_s), ("k_e", t.k_e)] {
            let p = whole.parameter(name).unwrap();
            assert!(rel(p.value, truth).abs() < 1e-3, "{stem}: {name} {}", p.value);
        }
    }
}

/// Every 2000th row of the drive simulator's 8 s exp3 log (41 samples at 5 Hz): the
/// steady-state equations' intervals of r_s, l_s and k_e all reach below zero (r_s within
/// about ±10 times its value), which passed with exit 0 before; now untrusted
/// (`undetermined`), naming each with its interval. Needs no development logs.
#[test]
fn telemetry_that_cannot_tell_a_parameter_from_zero_is_untrusted() {
    let cfg = DriveConfig { duration: 8.0, ..scenario("exp3", SPM_MOTOR).unwrap() };
    let e = simulate_drive(&cfg).unwrap().experiment.decimate(2000).unwrap();
    let fit = fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions::new(4)).unwrap();
    assert_eq!(fit.report.model, "pmsm_spm_steady");
    let w = fit.warnings.iter().find(|w| w.code == "undetermined").expect("undetermined");
    assert!(w.untrusted && !fit.trusted(), "{:?}", fit.warnings);
    for name in ["r_s", "l_s", "k_e"] {
        let p = fit.parameter(name).unwrap();
        assert!(p.value > 0.0 && p.ci95[0] < 0.0, "{name}: {} {:?}", p.value, p.ci95);
        assert!(w.message.contains(&format!("{name} ∈ [-")), "{name}: {}", w.message);
    }
}

/// The gym-electric-motor SPM log of moves (8 kHz, short plateaus) at every 80th row (100
/// Hz): R_s came out −1.6 % with an honest interval (|z| 0.5) and exit 0; the steady-state
/// fit's stated accuracy (R_s 0.5 %, K_e 0.05 % at three standard errors, issue 43) makes it
/// untrusted (`imprecise`, naming R_s and how well it is known); stated off, the same
/// estimate is trusted and covers the truth. At every 5000th row of the shared SPM
/// log with injections (15 rows, 3 smooth samples: 6 equations for 4 unknowns) the fit was refused
/// (an error, exit 1); now fitted and untrusted.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn telemetry_short_of_the_stated_accuracy_is_untrusted() {
    let (fast, t) = load("gem_spm_moves_idinj");
    let e = fast.decimate(80).unwrap();
    let one = std::slice::from_ref(&e);
    let fit = fit_pmsm(one, &PmsmFitOptions::new(t.n_p)).unwrap();
    let w = fit.warnings.iter().find(|w| w.code == "imprecise").expect("imprecise");
    assert!(
        w.untrusted && w.message.contains("r_s known to ±") && w.message.contains("(target 0.50 %)"),
        "{}",
        w.message
    );
    let r_s = fit.parameter("r_s").unwrap();
    assert!(rel(r_s.value, t.r_s).abs() > 5e-3, "r_s {:+.3e}: within the target now", rel(r_s.value, t.r_s));
    let off =
        fit_pmsm(one, &PmsmFitOptions { precision: Some(Vec::new()), ..PmsmFitOptions::new(t.n_p) }).unwrap();
    assert!(off.trusted(), "{:?}", off.warnings);
    for (name, truth) in [("r_s", t.r_s), ("k_e", t.k_e)] {
        let p = off.parameter(name).unwrap();
        assert_eq!(p.value, fit.parameter(name).unwrap().value);
        assert!((p.value - truth).abs() <= 3.0 * p.std_error, "{name}: {} against {truth}", p.value);
    }
    let (fast, t) = load("servo_spm_moves_idinj");
    let e = fast.decimate(5000).unwrap();
    let sparse = fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions::new(t.n_p)).unwrap();
    assert_eq!(sparse.report.model, "pmsm_spm_steady");
    assert!(
        !sparse.trusted() && sparse.warnings.iter().any(|w| w.code == "imprecise"),
        "{:?}",
        sparse.warnings
    );
    // Every 7000th row: 2 smooth samples, 4 equations for r_s, l_s, k_e (the control
    // period's term left out): 1 degree of freedom, K_e 0.7 % off at z 345, untrusted
    // whatever the stated accuracy (`few_samples`).
    let e = fast.decimate(7000).unwrap();
    let off = PmsmFitOptions { precision: Some(Vec::new()), ..PmsmFitOptions::new(t.n_p) };
    let fit = fit_pmsm(std::slice::from_ref(&e), &off).unwrap();
    assert_eq!(fit.report.fit.dof, 1, "{:?}", fit.report.fit);
    let w = fit.warnings.iter().find(|w| w.code == "few_samples").expect("few_samples");
    assert!(w.untrusted && w.message.contains("1 degrees of freedom"), "{}", w.message);
}

/// Every 20th and 80th row of the noise-free SPM log of moves: R_s +0.0025 % and +0.0016 %
/// with standard errors of 3e-6 relative (|z| 7.6 and 6.0, exit 0) before the parts' spread
/// widened the intervals; its four consecutive parts put R_s between +0.0005 % and +0.0035 %.
/// Now every parameter within 3 of its standard errors, trusted, with the note naming the
/// widened ones.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn noise_free_telemetry_intervals_cover_the_equations_error() {
    let (fast, t) = load("servo_spm_moves");
    for every in [20, 80] {
        let e = fast.decimate(every).unwrap();
        let fit = fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions::new(t.n_p)).unwrap();
        assert_eq!(fit.report.model, "pmsm_spm_steady");
        assert!(fit.trusted(), "every {every}th row: {:?}", fit.warnings);
        let note =
            fit.report.notes.iter().find(|n| n.contains("widened by the spread")).expect("widening note");
        assert!(note.contains("r_s ("), "{note}");
        for (name, truth) in [("r_s", t.r_s), ("l_s", t.l_d), ("k_e", t.k_e)] {
            let p = fit.parameter(name).unwrap();
            let z = (p.value - truth) / p.std_error;
            eprintln!("every {every}th row: {name} {:+.3e} (z {z:+.2})", rel(p.value, truth));
            assert!(z.abs() <= 3.0, "every {every}th row: {name} z {z}");
            // A widened parameter's interval takes Student's t with 3 degrees of freedom
            // (3.18), the others the fit's (about 1.96).
            let t = 0.5 * (p.ci95[1] - p.ci95[0]) / p.std_error;
            let widened = note.contains(&format!("{name} ("));
            assert_eq!(t > 3.0, widened, "{name}: half width {t} standard errors, widened {widened}");
        }
    }
}

/// Telemetry whose currents curve between samples, noise-free: i_d and i_q swing at 4.8 Hz
/// (ω h = 0.3 at 100 Hz) while the speed swings slowly about 1–4 rad/s (where L_s rests on
/// `L di/dt`; every quarter of the log alike, so the parts agree), the voltage from the
/// continuous equations with the exact derivatives. The central differences read `di/dt`
/// low by `(ω h)²/6 = 1.5 %`, a bias the equation errors' interval does not show: L_s
/// +0.35 % at z 7.3 without the truncation error in the interval. With it, every parameter
/// within 3 of its standard errors (L_s z 0.35), the estimates the same. Here `b` (−1.0 %
/// of L_s) is 2.9 times the error and of the other sign: a size, not a correction.
#[test]
fn curving_telemetry_intervals_cover_the_central_differences_error() {
    use greybox::pmsm::{Dynamics, SteadyOptions, steady_state};
    use greybox::{Channel, Experiment};
    let (r_s, l_s, k_e, n_p, h, w_swing) = (0.9, 4.5e-3, 0.27, 4u32, 0.01, 30.0);
    let n = 3000;
    let time = |k: usize| k as f64 * h;
    let w_m = |t: f64| 0.5 + 3.0 * (std::f64::consts::TAU * t / 2.5).sin();
    let i_d = |t: f64| 2.0 * (w_swing * t).sin();
    let i_q = |t: f64| 5.0 + 3.0 * (w_swing * t + 1.0).sin();
    let di_d = |t: f64| 2.0 * w_swing * (w_swing * t).cos();
    let di_q = |t: f64| 3.0 * w_swing * (w_swing * t + 1.0).cos();
    let sqrt_2_3 = (2.0f64 / 3.0).sqrt();
    let (mut ud, mut uq) = (Vec::new(), Vec::new());
    for k in 0..n {
        let t = time(k);
        let w_e = f64::from(n_p) * w_m(t);
        ud.push(r_s * i_d(t) + l_s * di_d(t) - w_e * l_s * i_q(t));
        uq.push(r_s * i_q(t) + l_s * di_q(t) + w_e * l_s * i_d(t) + sqrt_2_3 * k_e * w_m(t));
    }
    let column = |name: &str, unit: &str, f: &dyn Fn(f64) -> f64| {
        Channel::new(name, unit, (0..n).map(|k| f(time(k))).collect())
    };
    let e = Experiment::try_new(
        "curving",
        h,
        vec![
            Channel::new("ud", "V", ud),
            Channel::new("uq", "V", uq),
            column("id", "A", &i_d),
            column("iq", "A", &i_q),
            column("w_m", "rad/s", &w_m),
        ],
    )
    .unwrap();
    let one = std::slice::from_ref(&e);
    let raw = steady_state(one, n_p, MotorKind::Spm, &SteadyOptions::default()).unwrap();
    let doubled = SteadyOptions { derivative_half_width: 2, ..Default::default() };
    let wide = steady_state(one, n_p, MotorKind::Spm, &doubled).unwrap();
    let fit =
        fit_pmsm(one, &PmsmFitOptions { dynamics: Dynamics::Steady, ..PmsmFitOptions::new(n_p) }).unwrap();
    let note = fit.report.notes.iter().find(|n| n.contains("Richardson")).expect("truncation note");
    // The parts agree (each holds every speed), so the truncation error alone widens.
    assert!(!fit.report.notes.iter().any(|n| n.contains("widened by the spread")), "{:?}", fit.report.notes);
    for (name, truth) in [("r_s", r_s), ("l_s", l_s), ("k_e", k_e)] {
        let j = raw.names.iter().position(|x| x == name).unwrap();
        let p = fit.parameter(name).unwrap();
        assert_eq!(p.value, raw.theta[j], "{name}: the estimate stays");
        let (z_raw, z) = ((p.value - truth) / raw.std_error[j], (p.value - truth) / p.std_error);
        eprintln!(
            "{name} {:+.3e}: z {z_raw:+.1} without the truncation error, {z:+.2} with it",
            rel(p.value, truth)
        );
        assert!(z.abs() <= 3.0, "{name} z {z}: {note}");
        if name == "l_s" {
            assert!(z_raw.abs() > 5.0, "{name} z {z_raw} without the truncation error");
            // The size the interval takes: a third of the doubled differences' change.
            let b = (wide.theta[j] - raw.theta[j]) / 3.0;
            eprintln!("{name}: error {:.3e}, b {b:.3e}", p.value - truth);
            assert!(b.abs() >= 0.5 * (p.value - truth).abs(), "{name}: b {b} against the error");
        }
    }
}
