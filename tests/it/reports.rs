//! Reports apart from estimation: metrics on held-out data (`report::compare`, `greybox
//! validate`), one report format for the least-squares and the prediction-error fit, and
//! report files that never destroy data.

use crate::common::{pmsm_options, read};
use greybox::Experiment;
use greybox::pmsm::{MotorKind, PmsmSpm, SavedModel, VoltageHold, fit_pmsm, least_squares};
use greybox::report::compare;
use std::collections::BTreeSet;

const N_P: u32 = 4;

fn sample() -> Experiment {
    read(concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"), N_P, &Default::default())
        .expect("sample")
}

fn keys(json: &str) -> BTreeSet<String> {
    let v: serde_json::Value = serde_json::from_str(json).expect("JSON");
    v.as_object().expect("object").keys().cloned().collect()
}

/// A fit on the first 12 000 samples predicts the last 8 000 (not fitted on) to within the
/// noise-free model error: fit above 99 %, and the saved report gives back the same model.
#[test]
fn a_saved_fit_validates_on_held_out_data() {
    let e = sample();
    let (train, test) = (e.slice(0..12_000).unwrap(), e.slice(12_000..e.len()).unwrap());
    let fit = fit_pmsm(std::slice::from_ref(&train), &pmsm_options(N_P)).unwrap();
    let saved = SavedModel::from_json(&fit.to_json(), None, None).unwrap();
    assert_eq!((saved.kind, saved.pole_pairs, saved.hold), (MotorKind::Spm, N_P, fit.hold));
    for (j, name) in ["r_s", "l_s", "k_e"].iter().enumerate() {
        assert_eq!(saved.theta[j], fit.parameter(name).unwrap().value, "{name}");
    }
    let c = &saved.validate(std::slice::from_ref(&test)).unwrap()[0];
    assert_eq!(c.metrics.samples, test.len());
    assert!(c.metrics.fit_percent.iter().all(|f| *f > 99.0), "{:?}", c.metrics.fit_percent);
    // The same through the generic function, and a wrong model fits visibly worse.
    let direct = compare(&PmsmSpm::new(N_P, saved.hold), &test, &saved.theta, 3).unwrap();
    assert_eq!(direct.metrics, c.metrics);
    let wrong = compare(
        &PmsmSpm::new(N_P, saved.hold),
        &test,
        &[saved.theta[0], 2.0 * saved.theta[1], saved.theta[2]],
        3,
    )
    .unwrap();
    assert!(wrong.metrics.fit_percent[0] < c.metrics.fit_percent[0] - 1.0, "{:?}", wrong.metrics.fit_percent);
}

#[test]
fn a_report_without_pmsm_model_or_pole_pairs_is_refused() {
    let bad = |text: &str, p: Option<u32>| SavedModel::from_json(text, p, None).unwrap_err().to_string();
    assert!(bad("{}", None).contains("not a fit report"));
    let report = r#"{"model": "thermal", "parameters": []}"#;
    assert!(bad(report, Some(4)).contains("thermal"));
    let ls = r#"{"model": "pmsm_spm_least_squares", "parameters": [
        {"name": "r_s", "value": 1.0}, {"name": "l_s", "value": 1e-3}, {"name": "k_e", "value": 0.5}]}"#;
    assert!(bad(ls, None).contains("pole pairs"));
    let ok = SavedModel::from_json(ls, Some(4), Some(VoltageHold::Dq)).unwrap();
    assert_eq!((ok.theta.clone(), ok.hold), (vec![1.0, 1e-3, 0.5], VoltageHold::Dq));
}

/// `--method ls --json` and the PEM fit share the report's keys: every key of the LS
/// report is in the PEM report, and the PEM report adds only its PMSM wrapper's.
#[test]
fn least_squares_and_pem_reports_share_their_keys() {
    let e = sample();
    let ls = least_squares(std::slice::from_ref(&e), N_P, MotorKind::Spm).unwrap();
    let ls_report = ls.report(&[e.name().to_string()], N_P, 0.0);
    let pem = fit_pmsm(std::slice::from_ref(&e), &pmsm_options(N_P)).unwrap();
    let (ls_keys, pem_keys) = (keys(&ls_report.to_json()), keys(&pem.to_json()));
    for k in ["parameters", "derived", "fit", "diagnostics", "timing", "solver", "correlation"] {
        assert!(ls_keys.contains(k) && pem_keys.contains(k), "{k}");
    }
    assert!(ls_keys.is_subset(&pem_keys), "LS only: {:?}", ls_keys.difference(&pem_keys).collect::<Vec<_>>());
    let extra: BTreeSet<&str> = pem_keys.difference(&ls_keys).map(String::as_str).collect();
    let wrapper: BTreeSet<&str> = [
        "hold",
        "input",
        "cable_resistance",
        "hold_losses",
        "pole_pairs",
        "start_comparison",
        "pmsm_advice",
        "pmsm_notes",
    ]
    .into();
    assert!(extra.is_subset(&wrapper), "{extra:?}");
    // The parameter entries have the same fields, intervals included.
    let first = |json: &str| {
        keys(&serde_json::from_str::<serde_json::Value>(json).unwrap()["parameters"][0].to_string())
    };
    assert_eq!(first(&ls_report.to_json()), first(&pem.to_json()));
    let r_s = ls_report.parameter("r_s").unwrap();
    assert!(r_s.ci95[0] < r_s.value && r_s.value < r_s.ci95[1]);
    assert_eq!(
        ls_report.derived.iter().map(|d| d.name.as_str()).collect::<Vec<_>>(),
        ["k_t", "psi_f", "k_t_rms", "k_v", "k_m"]
    );
}

#[cfg(feature = "cli")]
mod cli {
    use crate::errors::greybox;

    /// A fresh path in the temporary folder, unique to this call, removed on drop.
    fn temp(name: &str) -> crate::common::TempFile {
        crate::common::TempFile::new("reports", name)
    }

    #[test]
    fn validate_writes_metrics_and_compare_data() {
        let (report, val, dir) = (temp("fit.json"), temp("val.json"), temp("cmp"));
        std::fs::create_dir_all(&dir).unwrap();
        let out =
            greybox(&["fit", "data/sample.csv.gz", "-p", "4", "-q", "--json", report.to_str().unwrap()]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let args = ["validate", "data/sample.csv.gz", "--params", report.to_str().unwrap()];
        let out = greybox(
            &[&args[..], &["--json", val.to_str().unwrap(), "--compare-dir", dir.to_str().unwrap()]].concat(),
        );
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&val).unwrap()).unwrap();
        let fit = &v["comparisons"][0]["metrics"]["fit_percent"];
        assert!(fit[0].as_f64().unwrap() > 99.0 && fit[1].as_f64().unwrap() > 99.0, "{fit}");
        let csv = std::fs::read_to_string(dir.join("sample.compare.csv")).unwrap();
        assert!(csv.starts_with("t,id,id_sim,iq,iq_sim\n"));
        assert_eq!(csv.lines().count(), 20_001);
        for p in [&report, &val] {
            let _ = std::fs::remove_file(p);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A report path that is an input is refused before any work; a failed fit leaves an
    /// existing report as it was.
    #[test]
    fn report_files_never_destroy_data() {
        let log = temp("log.csv");
        std::fs::copy("data/sample.csv.gz", &log).unwrap();
        let before = std::fs::read(&log).unwrap();
        let out = greybox(&["fit", log.to_str().unwrap(), "-p", "4", "--json", log.to_str().unwrap()]);
        assert!(!out.status.success());
        assert!(
            String::from_utf8_lossy(&out.stderr).contains("is an input"),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(std::fs::read(&log).unwrap(), before, "the log is intact");
        let report = temp("old.json");
        std::fs::write(&report, "{\"old\": true}\n").unwrap();
        let out = greybox(&["fit", "no/such/log.csv", "-p", "4", "--json", report.to_str().unwrap()]);
        assert!(!out.status.success());
        assert_eq!(
            std::fs::read_to_string(&report).unwrap(),
            "{\"old\": true}\n",
            "the old report is intact"
        );
        let _ = std::fs::remove_file(&log);
        let _ = std::fs::remove_file(&report);
    }
}

/// With white measurement noise and the right model, the residuals of the fit are white:
/// the fraction of the 25 lags beyond the 95 % bound stays near 5 % (at most 5 of 25, a
/// binomial tail of 1 %); the same residuals shifted by a slow drift (a model error) are
/// not white.
#[test]
fn fit_residuals_are_white_under_white_noise() {
    use crate::common::{Rng, exciting_signals, simulate_into};
    use greybox::pmsm::DqView;
    let (theta, h, n) = ([0.9, 4.5e-3, 0.539], 1e-4, 4000);
    let mut rng = Rng(7);
    let clean = simulate_into(
        &PmsmSpm::new(N_P, VoltageHold::Stator),
        &theta,
        h,
        exciting_signals(n, h, 250.0, 60.0, theta[2], &mut rng),
    );
    let mut s = DqView::try_new(&clean).unwrap().to_signals();
    for v in s.i_d.iter_mut().chain(s.i_q.iter_mut()) {
        *v += 0.05 * rng.normal();
    }
    let noisy = s.clone().into_experiment("noisy", h).unwrap();
    let options =
        greybox::pmsm::PmsmFitOptions { hold: greybox::pmsm::HoldChoice::Stator, ..pmsm_options(N_P) };
    let fit = fit_pmsm(&[noisy], &options).unwrap();
    for w in &fit.fit.whiteness {
        assert_eq!(w.autocorrelation.len(), 25);
        assert!(w.fraction_outside <= 0.2, "{:?}", w.autocorrelation);
    }
    let drift: Vec<f64> = (0..n).map(|k| 0.05 * rng.normal() + 0.05 * (k as f64 / 300.0).sin()).collect();
    let w = greybox::estimate::whiteness(&[&drift], 25);
    assert!(w.fraction_outside > 0.9, "{:?}", w.autocorrelation);
}
