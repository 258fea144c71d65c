//! Noise on the logged voltage and current (issue 43): the automatic voltage hold (MODEL.md
//! §4) keeps the stator hold when the two holds' losses differ by no more than the
//! residuals' noise explains (before, one noisy stator-held log in forty took the dq hold
//! by 0.06 % of its loss and gave K_e 7 standard errors off with exit 0); the output-error
//! fit finds the voltage noise's bias (`voltage_noise_bias`) and `--method auto` then takes
//! instrumental variables.

use crate::common::Rng;
use greybox::data::{Channel, Experiment};
use greybox::pmsm::{
    CsvOptions, Estimator, MotorKind, PmsmFitOptions, VoltageHold, fit_pmsm, fit_pmsm_by, read_log,
};

/// The shipped sample log (stator-held, 10 kHz) without its modulator reference, with white
/// noise of `sigma_u` \[V\] on the voltages and `sigma_i` \[A\] on the currents.
fn noisy_sample(seed: u64, sigma_u: f64, sigma_i: f64) -> Experiment {
    noisy(concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"), seed, sigma_u, sigma_i)
}

/// The log at `path` without its modulator reference, with white noise of `sigma_u` \[V\] on
/// the voltages and `sigma_i` \[A\] on the currents.
fn noisy(path: &str, seed: u64, sigma_u: f64, sigma_i: f64) -> Experiment {
    let e = read_log(path, &CsvOptions::default()).unwrap();
    let mut rng = Rng(seed);
    let channels = e
        .channels()
        .iter()
        .filter(|c| !c.name.ends_with("_ref"))
        .map(|c| {
            let sigma = match c.name.as_str() {
                "ud" | "uq" => sigma_u,
                "id" | "iq" => sigma_i,
                _ => 0.0,
            };
            Channel::new(
                &c.name,
                &c.unit,
                c.values.as_slice().iter().map(|v| v + sigma * rng.normal()).collect(),
            )
        })
        .collect();
    Experiment::try_new(e.name(), e.h(), channels).unwrap()
}

#[test]
fn holds_the_noise_ties_keep_the_stator_hold() {
    let mut dq_lower = 0;
    for seed in 1..=6 {
        let fit = fit_pmsm(&[noisy_sample(seed, 3.0, 0.05)], &PmsmFitOptions::new(4)).unwrap();
        let note =
            fit.pmsm_notes.iter().find(|n| n.contains("voltage hold chosen")).cloned().unwrap_or_default();
        assert_eq!(fit.hold, VoltageHold::Stator, "seed {seed}: {note}");
        // Losses as the note lists them: "(losses stator A, dq B)".
        let losses = note.rsplit("(losses ").next().unwrap_or("");
        let loss = |h: &str| -> f64 {
            let at = losses.find(&format!("{h} ")).map(|i| &losses[i + h.len() + 1..]).unwrap_or("");
            at.split([',', ')']).next().unwrap_or("").trim().parse().unwrap_or(f64::NAN)
        };
        if loss("dq") < loss("stator") {
            dq_lower += 1;
            assert!(note.contains("noise explains"), "seed {seed}: {note}");
        }
    }
    // The rule was exercised: some seed's dq loss was the lower.
    assert!(dq_lower > 0, "no seed tied the holds");
}

/// 3 V of voltage noise on the sample log: the output-error fit reads the noise's level off
/// its voltage equations (within 10 %), finds it biasing the estimate and is untrusted; the
/// automatic method takes instrumental variables, whose estimates lie within 3 standard
/// errors of the truth (R_s 0.9 Ω, L_s 4.5 mH, K_e 0.538888 V s/rad). Without the noise
/// neither happens.
#[test]
fn voltage_noise_takes_the_default_to_instrumental_variables() {
    let options = PmsmFitOptions::new(4);
    let noisy = [noisy_sample(1, 3.0, 0.05)];
    let oe = fit_pmsm(&noisy, &options).unwrap();
    let bias =
        oe.report.warnings.iter().find(|w| w.code == "voltage_noise_bias").expect("voltage_noise_bias");
    assert!(bias.untrusted, "{bias:?}");
    let sigma: f64 =
        bias.message.split("σ ≈ ").nth(1).and_then(|r| r.split(' ').next()).unwrap().parse().unwrap();
    assert!((sigma / 3.0 - 1.0).abs() < 0.1, "σ {sigma}");
    let auto = fit_pmsm_by(&noisy, &options, Estimator::Auto).unwrap();
    assert!(
        auto.report.notes.iter().any(|n| n.contains("took instrumental variables")),
        "{:?}",
        auto.report.notes
    );
    assert!(auto.report.warnings.iter().all(|w| w.code != "voltage_noise_bias"));
    for (name, truth) in [("r_s", 0.9), ("l_s", 4.5e-3), ("k_e", 0.538888)] {
        let p = auto.report.parameter(name).unwrap();
        assert!((p.value - truth).abs() < 3.0 * p.std_error, "{name} {} ± {}", p.value, p.std_error);
    }
    let pem = fit_pmsm_by(&noisy, &options, Estimator::PredictionError).unwrap();
    assert!(pem.report.warnings.iter().any(|w| w.code == "voltage_noise_bias"));
    let clean = fit_pmsm_by(&[noisy_sample(1, 0.0, 0.0)], &options, Estimator::Auto).unwrap();
    assert!(clean.report.warnings.iter().all(|w| w.code != "voltage_noise_bias"));
    assert!(clean.report.notes.iter().all(|n| !n.contains("took instrumental variables")));
}

/// 1 V of voltage noise and 0.03 A of current noise on the shared moves log (the issue's
/// Monte Carlo setting): where the output-error losses of the two holds are tied and their
/// IV estimates differ beyond 3 standard errors, `--method iv` is untrusted
/// (`hold_ambiguous`) as the automatic method is, with the same estimates; a given hold runs
/// no such check. Before, `--method iv` ran the IV at the tie's stator hold alone and exited
/// 0 where the automatic method exited 3 (200 of 200 seeds).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn instrumental_variables_check_the_hold_as_the_automatic_method() {
    crate::common::require_shared!();
    let path = crate::common::shared_file("servo_spm_moves_idinj.csv.gz");
    let options = PmsmFitOptions::new(4);
    let mut ambiguous = 0;
    for seed in 1..=2 {
        let noisy = [noisy(&path, seed, 1.0, 0.03)];
        let codes = |f: &greybox::pmsm::PmsmFit| -> Vec<String> {
            f.report.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.clone()).collect()
        };
        let auto = fit_pmsm_by(&noisy, &options, Estimator::Auto).unwrap();
        let iv = fit_pmsm_by(&noisy, &options, Estimator::InstrumentalVariables).unwrap();
        if !auto.report.notes.iter().any(|n| n.contains("took instrumental variables")) {
            continue;
        }
        let has = |f: &greybox::pmsm::PmsmFit| f.report.warnings.iter().any(|w| w.code == "hold_ambiguous");
        assert_eq!(has(&auto), has(&iv), "seed {seed}: auto {:?}, iv {:?}", codes(&auto), codes(&iv));
        for name in ["r_s", "l_s", "k_e"] {
            assert_eq!(auto.report.parameter(name).unwrap().value, iv.report.parameter(name).unwrap().value);
        }
        if has(&iv) {
            ambiguous += 1;
            let given = PmsmFitOptions { hold: greybox::pmsm::HoldChoice::Stator, ..options.clone() };
            let stator = fit_pmsm_by(&noisy, &given, Estimator::InstrumentalVariables).unwrap();
            assert!(
                stator.report.warnings.iter().all(|w| w.code != "hold_ambiguous"),
                "{:?}",
                codes(&stator)
            );
        }
    }
    assert!(ambiguous > 0, "no seed made the holds ambiguous");
}

/// The drive simulator's exp5 (100 000 samples at 10 kHz) with the motor of `kind` (the
/// surface or interior one), white noise of 1 V on the logged voltages, 0.03 A on the
/// currents, and an unmodelled inverter error of `v_dt` \[V\]; the instrumental-variable
/// fit of that model at the stator hold and the truth by parameter name.
fn exp5_iv(
    kind: MotorKind,
    seed: u64,
    v_dt: f64,
) -> (greybox::estimate::FitResult, Vec<(&'static str, f64)>) {
    use greybox::drive::{IPM_MOTOR, SPM_MOTOR, scenario, simulate_drive};
    let motor = match kind {
        MotorKind::Ipm => IPM_MOTOR,
        _ => SPM_MOTOR,
    };
    let mut cfg = scenario("exp5", motor).unwrap();
    (cfg.seed, cfg.sensors.voltage_noise, cfg.sensors.current_noise, cfg.inverter.v_dt) =
        (seed, 1.0, 0.03, v_dt);
    let log = simulate_drive(&cfg).unwrap();
    let options = PmsmFitOptions {
        model: kind,
        hold: greybox::pmsm::HoldChoice::Stator,
        ..PmsmFitOptions::new(motor.n_p)
    };
    let fit = fit_pmsm_by(&[log.experiment], &options, Estimator::InstrumentalVariables).unwrap();
    let (t, k_e) = (log.truth.start, log.truth.k_e);
    let truth = match kind {
        MotorKind::Ipm => vec![("r_s", t.r_s), ("l_d", t.l_d), ("l_q", t.l_q), ("k_e", k_e)],
        _ => vec![("r_s", t.r_s), ("l_s", t.l_d), ("k_e", k_e)],
    };
    (fit.report, truth)
}

/// Every parameter of `truth` (name, value) inside its 95 % interval in `fit`.
fn covers(fit: &greybox::estimate::FitResult, truth: &[(&str, f64)]) {
    for &(name, t) in truth {
        let p = fit.parameter(name).unwrap();
        assert!(p.ci95[0] <= t && t <= p.ci95[1], "{name}: {} {:?}, truth {t}", p.value, p.ci95);
    }
}

/// Input noise leaves a poor, coloured output-error residual (exp5's i_q fit about 40 %)
/// that is the noise floor: the instrumental-variable fit is not untrusted for it, says so,
/// and its intervals hold the truth; an inverter error that the noise does not explain (20 V,
/// the residual's mean square more than 1.25 times the noise's) keeps `poor_fit`.
#[test]
fn the_input_noise_floor_is_no_poor_fit() {
    let (fit, truth) = exp5_iv(MotorKind::Spm, 3, 0.0);
    let codes: Vec<&str> = fit.warnings.iter().map(|w| w.code.as_str()).collect();
    assert!(!codes.contains(&"poor_fit"), "{codes:?}");
    assert!(fit.fit.fit_percent.iter().any(|f| *f < greybox::estimate::POOR_FIT_PERCENT), "{:?}", fit.fit);
    assert!(fit.notes.iter().any(|n| n.contains("is the noise floor")), "{:?}", fit.notes);
    covers(&fit, &truth);
    let (fit, _) = exp5_iv(MotorKind::Spm, 3, 20.0);
    let codes: Vec<&str> = fit.warnings.iter().map(|w| w.code.as_str()).collect();
    assert!(codes.contains(&"poor_fit"), "{codes:?}");
    assert!(!fit.notes.iter().any(|n| n.contains("is the noise floor")), "{:?}", fit.notes);
}

/// The interior-magnet model's noise floor: each axis's voltage noise read off its own
/// one-step errors and carried through the coupled current equations. Input noise leaves
/// exp5's i_d fit about 72 % and i_q about 18 % (before: `poor_fit`, exit 3, with every
/// estimate inside its interval); the fit is not untrusted for it, says so, and its
/// intervals hold the truth. An inverter error of 20 V keeps `poor_fit`.
#[test]
fn the_interior_magnets_input_noise_floor_is_no_poor_fit() {
    let (fit, truth) = exp5_iv(MotorKind::Ipm, 3, 0.0);
    let codes: Vec<&str> = fit.warnings.iter().map(|w| w.code.as_str()).collect();
    assert!(!codes.contains(&"poor_fit"), "{codes:?}");
    assert!(fit.fit.fit_percent.iter().all(|f| *f < greybox::estimate::POOR_FIT_PERCENT), "{:?}", fit.fit);
    assert!(
        fit.notes.iter().any(|n| n.contains("is the noise floor") && n.contains(" on q")),
        "{:?}",
        fit.notes
    );
    covers(&fit, &truth);
    let (fit, _) = exp5_iv(MotorKind::Ipm, 3, 20.0);
    let codes: Vec<&str> = fit.warnings.iter().map(|w| w.code.as_str()).collect();
    assert!(codes.contains(&"poor_fit"), "{codes:?}");
    assert!(!fit.notes.iter().any(|n| n.contains("is the noise floor")), "{:?}", fit.notes);
}

/// A wrong voltage hold under strong voltage noise: the other simulator's SPM log of moves
/// holds the dq voltage; with 3 V + 0.03 A the two holds' output-error losses tie, the
/// stator hold is kept and the noise floor claims the poor fit. The holds' IV estimates
/// differ by several standard errors of their difference (the batches' paired jackknife),
/// which the combined standard errors hid (9 of 10 seeds passed, `k_e` covered in 1 of 9):
/// every seed is untrusted (`hold_ambiguous`).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn a_wrong_hold_hidden_by_voltage_noise_is_ambiguous() {
    crate::common::require_shared!();
    let path = crate::common::shared_file("gem_spm_moves_idinj.csv.gz");
    let options = PmsmFitOptions::new(crate::common::truth("gem_spm_moves_idinj").n_p);
    for seed in 1..=3 {
        let fit = fit_pmsm_by(&[noisy(&path, seed, 3.0, 0.03)], &options, Estimator::Auto).unwrap();
        let untrusted: Vec<&str> =
            fit.report.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.as_str()).collect();
        assert!(untrusted.contains(&"hold_ambiguous"), "seed {seed}: {untrusted:?}");
    }
}

/// A noisy log that carries a modulator's reference `ud_ref, uq_ref` (the drive simulator's
/// exp3, stator-held, 1 V + 0.03 A): the reference settles the stator hold, as in the
/// output-error fit, and the noise does not reopen it; the automatic fit (instrumental
/// variables) is trusted and its intervals hold the truth. The same log without the
/// reference is untrusted (`hold_ambiguous`): its holds' IV estimates differ in k_e by about
/// 5 standard errors, and only the user knows how the voltage was held.
#[test]
fn a_modulator_reference_settles_the_hold_under_noise() {
    use greybox::drive::{SPM_MOTOR, scenario, simulate_drive};
    let mut cfg = scenario("exp3", SPM_MOTOR).unwrap();
    (cfg.seed, cfg.sensors.voltage_noise, cfg.sensors.current_noise) = (1, 1.0, 0.03);
    let log = simulate_drive(&cfg).unwrap();
    let truth = [log.truth.start.r_s, log.truth.start.l_d, log.truth.k_e];
    let e = log.experiment;
    assert!(e.get("ud_ref").is_some() && e.get("uq_ref").is_some());
    let options = PmsmFitOptions::new(4);
    let fit = fit_pmsm_by(std::slice::from_ref(&e), &options, Estimator::Auto).unwrap();
    let untrusted: Vec<&str> =
        fit.report.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.as_str()).collect();
    assert!(untrusted.is_empty(), "{untrusted:?}");
    assert!(fit.report.notes.iter().any(|n| n.contains("took instrumental variables")));
    assert_eq!(fit.hold, VoltageHold::Stator);
    for (name, t) in ["r_s", "l_s", "k_e"].iter().zip(truth) {
        let p = fit.report.parameter(name).unwrap();
        assert!(p.ci95[0] <= t && t <= p.ci95[1], "{name}: {} {:?}, truth {t}", p.value, p.ci95);
    }
    let channels = e.channels().iter().filter(|c| !c.name.ends_with("_ref")).cloned().collect();
    let bare = Experiment::try_new(e.name(), e.h(), channels).unwrap();
    let fit = fit_pmsm_by(&[bare], &options, Estimator::Auto).unwrap();
    assert!(fit.report.warnings.iter().any(|w| w.code == "hold_ambiguous" && w.untrusted));
}

/// White noise on a held voltage is no point sampling: on the shared 10 kHz servo log of
/// moves with 1 V and 0.03 A, the trapezoid's refit beat the noise bound `2/(1 + a)` in 74
/// of 100 seeds (`point_sampled_voltage`, untrusted); with the rotation in the bound and the
/// bound checked at the fit's own estimate, 3 of 100 (seeds 1–100); with the refit's ratio
/// required to beat it by 3 of its standard errors (about 0.0018 here, against excesses of
/// at most 0.0014), none. Eight seeds: none.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn noise_on_a_held_voltage_is_no_point_sampling() {
    crate::common::require_shared!();
    let path = crate::common::shared_file("servo_spm_moves.csv.gz");
    let options = PmsmFitOptions { hold: greybox::pmsm::HoldChoice::Stator, ..PmsmFitOptions::new(4) };
    let flagged = (1..=8)
        .filter(|&seed| {
            let fit = fit_pmsm_by(&[noisy(&path, seed, 1.0, 0.03)], &options, Estimator::Auto).unwrap();
            fit.report.warnings.iter().any(|w| w.code == "point_sampled_voltage")
        })
        .count();
    assert_eq!(flagged, 0, "{flagged} of 8 seeds called point-sampled");
}

/// The interior-magnet model reads the voltage's noise off its own one-step errors: 1 V of
/// voltage noise and 0.03 A of current noise on the shared IPM log (the setting;
/// before, `--method auto` kept output error there: l_d 1.6 % high at 4 standard errors,
/// exit 0) read as 1 V within 15 %, and the automatic method takes instrumental variables,
/// within 3 standard errors of the truth. The other simulator's noisy IPM log, whose
/// 0.65 A of current noise reads at speed as `ω_e L σ_i`, about a volt, in the voltage
/// equations, is not taken for voltage noise (its 0.05 V is not told from zero).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn an_interior_magnet_log_with_voltage_noise_takes_instrumental_variables() {
    crate::common::require_shared!();
    let t = crate::common::truth("ipm_moves_idinj");
    let options = PmsmFitOptions { model: greybox::pmsm::MotorKind::Ipm, ..PmsmFitOptions::new(t.n_p) };
    let noisy = [noisy(&crate::common::shared_file("ipm_moves_idinj.csv.gz"), 3, 1.0, 0.03)];
    let pem = fit_pmsm_by(&noisy, &options, Estimator::PredictionError).unwrap();
    let bias =
        pem.report.warnings.iter().find(|w| w.code == "voltage_noise_bias").expect("voltage_noise_bias");
    let sigma: f64 =
        bias.message.split("σ ≈ ").nth(1).and_then(|r| r.split(' ').next()).unwrap().parse().unwrap();
    assert!((sigma - 1.0).abs() < 0.15, "σ {sigma}");
    let auto = fit_pmsm_by(&noisy, &options, Estimator::Auto).unwrap();
    assert!(auto.report.notes.iter().any(|n| n.contains("took instrumental variables")));
    for (name, truth) in [("r_s", t.r_s), ("l_d", t.l_d), ("l_q", t.l_q), ("k_e", t.k_e)] {
        let p = auto.report.parameter(name).unwrap();
        assert!((p.value - truth).abs() < 3.0 * p.std_error, "{name} {} ± {}", p.value, p.std_error);
    }
    let (gem, g) = crate::common::load("gem_ipm_moves_idinj_noisy");
    let options = PmsmFitOptions { model: greybox::pmsm::MotorKind::Ipm, ..PmsmFitOptions::new(g.n_p) };
    let fit = fit_pmsm_by(&[gem], &options, Estimator::PredictionError).unwrap();
    assert!(fit.report.warnings.iter().all(|w| w.code != "voltage_noise_bias"), "{:?}", fit.report.warnings);
}
