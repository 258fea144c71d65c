//! Trust (issue: no data loss, no confident wrong answer): concurrent report writers, honest
//! exit codes, and the detectors of the setup mistakes that otherwise give a confident wrong
//! answer, reproduced from the development logs.

use crate::common::{load, pmsm_options};
use greybox::Experiment;
use greybox::data::Channel;
use greybox::pmsm::{HoldChoice, MotorKind, PmsmFitOptions, Scale, VoltageInput, fit_pmsm};
use greybox::report::format_eng;

/// 200 threads writing different reports to one path leave one whole report, never a mix.
#[test]
fn concurrent_writers_leave_one_valid_report() {
    let dir = crate::common::TempDir::new("concurrent");
    let path = dir.join(format!("greybox-concurrent-{}.json", std::process::id()));
    std::thread::scope(|s| {
        for i in 0..200 {
            let path = &path;
            s.spawn(move || {
                let text = format!("{{\"writer\": {i}, \"pad\": \"{}\"}}", "x".repeat(1000 + 37 * i));
                greybox::data::write_atomic(path, |w| w.write_all(text.as_bytes())).unwrap();
            });
        }
    });
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let i = v["writer"].as_u64().unwrap() as usize;
    assert_eq!(v["pad"].as_str().unwrap().len(), 1000 + 37 * i);
    let _ = std::fs::remove_file(&path);
    let leftovers = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| {
            e.file_name().to_string_lossy().starts_with(&format!(".greybox-tmp.{}.", std::process::id()))
                && e.file_name()
                    .to_string_lossy()
                    .ends_with(&format!("greybox-concurrent-{}.json", std::process::id()))
        })
        .count();
    assert_eq!(leftovers, 0, "temporary files left behind");
}

/// Exit codes: a fit stopped by the iteration limit writes its report, flags
/// `not_converged` and exits 3 (0 with --allow-unconverged); an absurd tolerance is refused
/// with exit code 1 before anything is written.
#[cfg(feature = "cli")]
#[test]
fn exit_codes_tell_untrusted_results_apart() {
    use crate::errors::greybox;
    let dir = crate::common::TempDir::new("exit");
    let json = dir.join("exit.json");
    let j = json.to_str().unwrap();
    // One iteration from a poor start: the fit stops unconverged.
    let stopped = ["fit", "data/sample.csv.gz", "-p", "4", "-q", "--max-iters", "1", "--start", "2,0.01,0.8"];
    let out = greybox(&[&stopped[..], &["--json", j]].concat());
    assert_eq!(out.status.code(), Some(3), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(
        v["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w["code"] == "not_converged" && w["untrusted"] == true)
    );
    let out = greybox(&[&stopped[..], &["--allow-unconverged"]].concat());
    assert_eq!(out.status.code(), Some(0));
    std::fs::remove_file(&json).unwrap();
    let out = greybox(&["fit", "data/sample.csv.gz", "-p", "4", "--ftol", "1e300", "--json", j]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("ftol"));
    assert!(!json.exists());
    let out = greybox(&["fit", "data/sample.csv.gz", "-p", "4", "-q"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
}

fn scaled(e: &Experiment, name: &str, factor: f64) -> Experiment {
    let c = e.get(name).unwrap();
    let values = c.values.iter().map(|v| v * factor).collect();
    e.clone().with_channel(Channel::new(name, &c.unit, values)).unwrap()
}

fn codes(fit: &greybox::pmsm::PmsmFit) -> Vec<(String, bool, String)> {
    fit.warnings.iter().map(|w| (w.code.clone(), w.untrusted, w.message.clone())).collect()
}

/// The silent-wrongness cases of the trust issue on the servo log: each gives an untrusted
/// warning (exit code 3) naming the likely mistake, or an error; the right setup gives none.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn setup_mistakes_are_named() {
    crate::common::require_shared!();
    let (e, t) = load("servo_spm_moves_idinj");
    let e = e.slice(0..30_000).unwrap();
    let fit = |e: &Experiment, n_p: u32| fit_pmsm(std::slice::from_ref(e), &pmsm_options(n_p)).unwrap();
    let untrusted = |f: &greybox::pmsm::PmsmFit, code: &str, says: &str| {
        let c = codes(f);
        let hit = c.iter().find(|(k, u, _)| k == code && *u);
        eprintln!("{code}: {:?}", hit.map(|h| &h.2));
        assert!(hit.is_some_and(|(_, _, m)| m.contains(says)), "{code} / {says}: {c:?}");
        assert!(!f.trusted());
    };
    let right = fit(&e, t.n_p);
    assert!(right.trusted(), "{:?}", codes(&right));
    // Wrong pole pairs.
    for n_p in [3, 8] {
        untrusted(&fit(&e, n_p), "pole_pairs", "4 pole pairs");
    }
    // Electrical speed read as mechanical.
    let electrical = scaled(&e, "w_m", f64::from(t.n_p));
    let f = fit(&electrical, t.n_p);
    untrusted(&f, "speed_unit", "electrical");
    untrusted(&f, "pole_pairs", "1 pole pairs");
    // rpm read as rad/s.
    untrusted(&fit(&scaled(&e, "w_m", 30.0 / std::f64::consts::PI), t.n_p), "speed_unit", "rpm");
    // Time in ms read as s: refused before the fit, naming the unit; forced, the speed
    // check names the time column.
    let ms = Experiment::try_new("ms", 1e3 * e.h(), e.channels().to_vec()).unwrap();
    let err = fit_pmsm(std::slice::from_ref(&ms), &pmsm_options(t.n_p)).unwrap_err().to_string();
    assert!(err.contains("--time-unit ms"), "{err}");
    let forced = PmsmFitOptions { force: true, ..pmsm_options(t.n_p) };
    untrusted(&fit_pmsm(std::slice::from_ref(&ms), &forced).unwrap(), "speed_unit", "milliseconds");
    // RMS currents or power-invariant dq cannot be told from the data: a notice gives the
    // estimates under the other conventions.
    let notice = codes(&right).into_iter().find(|(k, u, _)| k == "scaling_assumed" && !u).unwrap();
    assert!(notice.2.contains("RMS") && notice.2.contains("power-invariant"), "{}", notice.2);
    // Peak currents read as RMS (`--current-scale rms`: ×√2 on reading) give r_s ÷√2; the
    // notice then offers the peak reading, the right fit's r_s, not a further ÷√2.
    let s2 = std::f64::consts::SQRT_2;
    let as_rms = scaled(&scaled(&e, "id", s2), "iq", s2);
    let read = PmsmFitOptions { read_scales: [Scale::Rms, Scale::Peak], ..pmsm_options(t.n_p) };
    let wrong = fit_pmsm(std::slice::from_ref(&as_rms), &read).unwrap();
    let r_s = |f: &greybox::pmsm::PmsmFit| f.report.parameter("r_s").unwrap().value;
    assert!((r_s(&wrong) * s2 / r_s(&right) - 1.0).abs() < 1e-6, "{} against {}", r_s(&wrong), r_s(&right));
    let notice = codes(&wrong).into_iter().find(|(k, u, _)| k == "scaling_assumed" && !u).unwrap();
    let offered =
        format!("If the currents were peak values, not RMS: r_s {}", format_eng(r_s(&wrong) * s2, "ohm", 5));
    assert!(notice.2.contains(&offered) && notice.2.contains("--current-scale rms"), "{}", notice.2);
    assert_eq!(format_eng(r_s(&wrong) * s2, "ohm", 5), format_eng(r_s(&right), "ohm", 5));
    // A surface-magnet model on the salient log is refused, naming the fix.
    let (ipm, t) = load("ipm_moves_idinj");
    let spm = PmsmFitOptions { model: MotorKind::Spm, ..pmsm_options(t.n_p) };
    let err = fit_pmsm(std::slice::from_ref(&ipm), &spm).unwrap_err();
    assert!(err.to_string().contains("--model ipm"), "{err}");
    // Before any other error the options or the fits give: a start of the wrong length, a
    // dq hold with the reference voltage.
    for other in [
        PmsmFitOptions { start: Some(vec![1.0, 2.0]), ..spm.clone() },
        PmsmFitOptions { hold: HoldChoice::Dq, input: VoltageInput::REFERENCE, ..spm.clone() },
    ] {
        let err = fit_pmsm(std::slice::from_ref(&ipm), &other).unwrap_err();
        assert!(err.to_string().contains("--model ipm"), "{err}");
    }
}

/// A wrong pole-pair count on an interior-magnet log is named even where the least-squares
/// scan hardly prefers the right one (its inductances and `k_e` absorb much of the error):
/// on the other simulator's IPM log (4 pole pairs, dq-held) fitted at 3 or 5 with the hold
/// given, the fit left with exit 0 before (a set-aside log of the same simulator at 3 pole
/// pairs, fitted at 4: `l_q` 21 % low); the prediction-error fit at the scan's choice
/// decides now.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn a_wrong_pole_pair_count_of_an_interior_magnet_log_is_named() {
    crate::common::require_shared!();
    let (e, t) = load("gem_ipm_moves_idinj");
    for n_p in [t.n_p - 1, t.n_p + 1] {
        let options = PmsmFitOptions { model: MotorKind::Ipm, hold: HoldChoice::Dq, ..pmsm_options(n_p) };
        let fit = fit_pmsm(std::slice::from_ref(&e), &options).unwrap();
        let c = codes(&fit);
        let says = format!("{} pole pairs", t.n_p);
        assert!(c.iter().any(|(k, u, m)| k == "pole_pairs" && *u && m.contains(&says)), "n_p {n_p}: {c:?}");
    }
}

/// The shipped sample log (`data/sample.csv.gz`: 4 pole pairs, noise-free).
fn sample() -> Experiment {
    greybox::pmsm::read_log(concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"), &Default::default())
        .unwrap()
}

/// A parameter at its bound is flagged, with no interval, and makes the fit untrusted.
#[test]
fn a_parameter_at_a_bound_has_no_interval() {
    let e = sample();
    let options = PmsmFitOptions {
        bounds: vec![("r_s".into(), 0.95, 2.0)],
        start: Some(vec![1.0, 4.5e-3, 0.54]),
        ..pmsm_options(4)
    };
    let fit = fit_pmsm(&[e], &options).unwrap();
    let r = fit.parameter("r_s").unwrap();
    assert!(r.at_bound && r.std_error.is_nan() && r.ci95.iter().all(|c| c.is_nan()), "{r:?}");
    assert!(fit.warnings.iter().any(|w| w.code == "parameter_at_bound" && w.message.contains("r_s")));
    assert!(!fit.trusted());
}

/// The shipped sample log with `[c_d, c_q]` \[A\] added to its dq currents, and a phase
/// current's offset `phase` \[A\] (constant in the stator frame, turning in dq at its 4 pole
/// pairs).
fn with_current_offset(e: &Experiment, [c_d, c_q]: [f64; 2], phase: f64) -> Experiment {
    let theta: Vec<f64> = e.channel("theta_m").unwrap().iter().map(|t| 4.0 * t).collect();
    let shifted = |name: &str, c: f64, turn: fn(f64) -> f64| {
        let values =
            e.channel(name).unwrap().iter().zip(&theta).map(|(v, t)| v + c + 2.0 / 3.0 * phase * turn(*t));
        Channel::new(name, "A", values.collect())
    };
    e.clone()
        .with_channel(shifted("id", c_d, f64::cos))
        .unwrap()
        .with_channel(shifted("iq", c_q, |t| -t.sin()))
        .unwrap()
}

/// A constant offset of the logged dq currents (issue 43; helper-38 found exit 0 with r_s
/// 3–4 % low on independent logs): 0.1 A on i_q of the noise-free sample puts l_s 4 % low at
/// 10 standard errors, 0.1 A on i_d k_e 0.4 % low at 30; both are named (exit 3) with the
/// offset. The log as logged, and with a phase current's offset of 0.3 A, which turns in
/// dq and leaves every estimate inside its interval, are not.
#[test]
fn a_current_offset_is_named() {
    let e = sample();
    let offset_named = |log: Experiment| {
        let fit = fit_pmsm(&[log], &pmsm_options(4)).unwrap();
        let c = codes(&fit);
        (c.iter().any(|(k, u, m)| k == "current_offset" && *u && m.contains("look offset")), c)
    };
    for c in [[0.0, 0.1], [0.1, 0.0]] {
        let (named, codes) = offset_named(with_current_offset(&e, c, 0.0));
        assert!(named, "{c:?}: {codes:?}");
    }
    for (what, log) in [("as logged", e.clone()), ("phase offset", with_current_offset(&e, [0.0; 2], 0.3))] {
        let (named, codes) = offset_named(log);
        assert!(!named, "{what}: {codes:?}");
    }
}

/// The shipped sample log as a drive whose encoder zero sits `delta` \[°, electrical\] ahead
/// of the magnet axis logs it: every dq current and voltage turned by `−delta`, the rotor
/// angle `delta / n_p` ahead.
fn with_angle_offset(e: &Experiment, delta: f64) -> Experiment {
    let (s, c) = delta.to_radians().sin_cos();
    let mut out = e.clone();
    for (d, q, unit) in [("ud", "uq", "V"), ("id", "iq", "A")] {
        let (xd, xq) = (e.channel(d).unwrap(), e.channel(q).unwrap());
        let rd = xd.iter().zip(xq.iter()).map(|(x, y)| c * x + s * y).collect();
        let rq = xd.iter().zip(xq.iter()).map(|(x, y)| -s * x + c * y).collect();
        out = out
            .with_channel(Channel::new(d, unit, rd))
            .unwrap()
            .with_channel(Channel::new(q, unit, rq))
            .unwrap();
    }
    let theta = e.channel("theta_m").unwrap().iter().map(|t| t + delta.to_radians() / 4.0).collect();
    out.with_channel(Channel::new("theta_m", "rad", theta)).unwrap()
}

/// A dq frame turned from the rotor's (an encoder zero off the magnet axis; issue 43: no
/// wrong answer with exit 0). Turned by 1° on the shared surface-magnet log, the fit put
/// l_s 3.7 % low outside its interval with exit 0. On the noise-free sample, 0.5° and −1°
/// are named with the angle within 0.05° (exit 3); the log as logged is not.
#[test]
fn an_angle_offset_is_named() {
    let e = sample();
    // The angle the warning gives [°], if it is given.
    let named = |log: Experiment| {
        let fit = fit_pmsm(&[log], &pmsm_options(4)).unwrap();
        let c = codes(&fit);
        let angle = c.iter().find(|(k, u, _)| k == "angle_offset" && *u).and_then(|(_, _, m)| {
            m.split("turned from the rotor's by about ").nth(1)?.split('°').next()?.parse::<f64>().ok()
        });
        (angle, c)
    };
    for delta in [0.5, -1.0] {
        let (angle, codes) = named(with_angle_offset(&e, delta));
        assert!(angle.is_some_and(|a| (a - delta).abs() < 0.05), "{delta}: {codes:?}");
    }
    let (angle, codes) = named(e);
    assert!(angle.is_none(), "as logged: {codes:?}");
}

/// A noisy interior-magnet log with its speed in rpm: the output-error fit names the
/// speed's unit and finds the voltage noise biasing it, so `--method auto` turns to
/// instrumental variables, whose iteration then leaves the positive parameters. That ended
/// with an error saying only "the instruments are too weak" (exit 1); the output-error fit
/// is reported now, untrusted and naming the unit, with a note; `--method iv`'s error names
/// the output-error fit's warnings.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn failed_instrumental_variables_leave_the_output_error_fit_naming_the_mistake() {
    use greybox::pmsm::{Estimator, fit_pmsm_by};
    crate::common::require_shared!();
    let (e, t) = load("gem_ipm_moves_idinj_noisy");
    let rpm: Vec<f64> = e.channel("w_m").unwrap().iter().map(|w| w * 30.0 / std::f64::consts::PI).collect();
    let e = e.with_channel(Channel::new("w_m", "rad/s", rpm)).unwrap();
    let options = PmsmFitOptions { model: MotorKind::Ipm, ..pmsm_options(t.n_p) };
    let auto = fit_pmsm_by(std::slice::from_ref(&e), &options, Estimator::Auto).unwrap();
    let c = codes(&auto);
    assert!(!auto.trusted(), "{c:?}");
    assert!(c.iter().any(|(k, u, m)| k == "columns" && *u && m.contains("--speed-unit rpm")), "{c:?}");
    assert!(auto.notes.iter().any(|n| n.contains("but they failed")), "{:?}", auto.notes);
    let iv = fit_pmsm_by(&[e], &options, Estimator::InstrumentalVariables).unwrap_err().to_string();
    assert!(iv.contains("instruments are too weak") && iv.contains("columns"), "{iv}");
}
