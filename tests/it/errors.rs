//! Bad input to the estimator and the command line: clear errors naming the culprit, no panic.

use crate::common::{Signals, pmsm_options};
use greybox::data::Channel;
use greybox::estimate::{PemOptions, Tolerances, fit};
use greybox::model::{GreyBoxModel, Parameter, Signal};
use greybox::pmsm::PmsmError;
use greybox::pmsm::{PmsmFitOptions, PmsmSpm, VoltageHold, fit_pmsm};
use greybox::{Error, Experiment, Result};
#[cfg(feature = "cli")] // the `greybox` binary needs the `cli` feature
use std::process::Command;

fn sample() -> Experiment {
    crate::common::read(concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"), 4, &Default::default())
        .unwrap()
}

/// `x[k+1] = a x[k] + u[k]`, output x: unstable for |a| > 1.
pub(crate) struct Scalar {
    pub(crate) p: Vec<Parameter>,
}
impl GreyBoxModel for Scalar {
    type Inputs = Vec<f64>;
    type Coefficients = f64;
    fn name(&self) -> &str {
        "scalar"
    }
    fn n_states(&self) -> usize {
        1
    }
    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new("y", "-")]
    }
    fn input_channels(&self) -> Vec<String> {
        vec!["u".into()]
    }
    fn parameters(&self) -> &[Parameter] {
        &self.p
    }
    fn prepare(&self, e: &Experiment) -> Result<Vec<f64>> {
        Ok(e.channel("u")?.to_vec())
    }
    fn coefficients(&self, th: &[f64], _: &Vec<f64>) -> Result<f64> {
        Ok(th[0])
    }
    fn step(&self, a: &f64, u: &Vec<f64>, k: usize, x: &[f64], xn: &mut [f64]) {
        xn[0] = a * x[0] + u[k];
    }
}

fn scalar_experiment(a: f64, n: usize) -> Experiment {
    let u: Vec<f64> = (0..n).map(|k| ((k * 7919) % 13) as f64 - 6.0).collect();
    let mut x = vec![0.0; n];
    for k in 1..n {
        x[k] = a * x[k - 1] + u[k - 1];
    }
    Experiment::try_new("scalar", 1e-3, vec![Channel::new("u", "-", u), Channel::new("y", "-", x)]).unwrap()
}

#[test]
fn diverging_simulation_at_the_start_is_an_error_naming_sample_and_parameters() {
    let m = Scalar { p: vec![Parameter::free("a", "-", 1.0)] };
    let e = scalar_experiment(0.9, 3000);
    let err = fit(&m, &[e], &[3.0], &PemOptions::default()).unwrap_err();
    assert!(matches!(err, Error::SimulationDiverged { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("scalar") && msg.contains("a = 3e0") && msg.contains("diverged at sample"), "{msg}");
}

#[test]
fn trial_steps_into_divergence_are_rejected_not_fatal() {
    // Start on the stable side near the edge: trial steps beyond |a| = 1 blow up over 3000
    // samples and must count as rejected steps.
    let m = Scalar { p: vec![Parameter::free("a", "-", 1.0)] };
    let e = scalar_experiment(0.9, 3000);
    let r = fit(&m, &[e], &[0.999], &PemOptions::default()).unwrap();
    assert!(r.solver.success, "{}", r.solver.termination);
    assert!((r.parameters[0].value - 0.9).abs() < 1e-9, "{}", r.parameters[0].value);
}

#[test]
fn bounds_that_exclude_the_start_are_named() {
    let opts = PmsmFitOptions {
        start: Some(vec![0.9, 4.5e-3, 0.54]),
        bounds: vec![("r_s".into(), 1.0, 2.0)],
        ..pmsm_options(4)
    };
    let err = fit_pmsm(&[sample()], &opts).unwrap_err();
    assert!(matches!(err, Error::StartOutsideBounds { .. }), "{err:?}");
    assert!(err.to_string().contains("r_s"), "{err}");
}

#[test]
fn empty_or_reversed_bounds_are_named() {
    for (lo, hi) in [(2.0, 1.0), (1.0, 1.0), (f64::NAN, 1.0)] {
        let opts = PmsmFitOptions { bounds: vec![("l_s".into(), lo, hi)], ..pmsm_options(4) };
        let err = fit_pmsm(&[sample()], &opts).unwrap_err();
        assert!(matches!(err, Error::InvalidBounds { .. }), "{err:?}");
        assert!(err.to_string().contains("l_s"), "{err}");
    }
}

#[test]
fn non_positive_start_of_a_positive_parameter_is_named() {
    let opts = PmsmFitOptions { start: Some(vec![0.9, -4.5e-3, 0.54]), ..pmsm_options(4) };
    let err = fit_pmsm(&[sample()], &opts).unwrap_err();
    assert!(err.to_string().contains("l_s"), "{err}");
}

#[test]
fn option_errors_name_the_option() {
    let e = sample();
    let cases: Vec<(PmsmFitOptions, &str)> = vec![
        (PmsmFitOptions { start: Some(vec![1.0, 2.0]), ..pmsm_options(4) }, "start"),
        (PmsmFitOptions { fixed: vec!["nope".into()], ..pmsm_options(4) }, "nope"),
        (
            PmsmFitOptions {
                pem: PemOptions { per_experiment: vec!["x".into()], ..Default::default() },
                ..pmsm_options(4)
            },
            "`x`",
        ),
        (
            PmsmFitOptions { pem: PemOptions { horizon: Some(0), ..Default::default() }, ..pmsm_options(4) },
            "horizon",
        ),
        (
            PmsmFitOptions { pem: PemOptions { huber: Some(-1.0), ..Default::default() }, ..pmsm_options(4) },
            "huber",
        ),
        (
            PmsmFitOptions {
                pem: PemOptions {
                    tolerances: Tolerances { ftol: f64::NAN, ..Default::default() },
                    ..Default::default()
                },
                ..pmsm_options(4)
            },
            "ftol",
        ),
        (
            PmsmFitOptions {
                pem: PemOptions { output_weights: Some(vec![1.0, 0.0]), ..Default::default() },
                ..pmsm_options(4)
            },
            "output_weights",
        ),
        (
            PmsmFitOptions {
                pem: PemOptions { output_weights: Some(vec![1e200, 1e200]), ..Default::default() },
                ..pmsm_options(4)
            },
            "output_weights",
        ),
    ];
    for (opts, culprit) in cases {
        let err = fit_pmsm(std::slice::from_ref(&e), &opts).unwrap_err();
        assert!(err.to_string().contains(culprit), "expected `{culprit}` in: {err}");
    }
    let err = fit_pmsm(&[], &pmsm_options(4)).unwrap_err();
    assert!(err.to_string().contains("no log"), "{err}");
}

/// The output weights' common scale changes neither the estimate nor its interval, up to
/// the accepted range's edge (where, past it, the covariance's sums overflowed and the
/// intervals had zero width with exit 0).
#[test]
fn output_weights_common_scale_changes_no_interval() {
    let e = sample();
    let fit = |w: f64| {
        let pem = PemOptions { output_weights: Some(vec![w, w]), ..Default::default() };
        fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions { pem, ..pmsm_options(4) }).unwrap()
    };
    let (one, big) = (fit(1.0), fit(1e100));
    for (a, b) in one.parameters.iter().zip(&big.parameters) {
        assert!(b.std_error > 0.0, "{}: zero width", b.name);
        assert!((a.value - b.value).abs() <= 1e-9 * a.value.abs(), "{}: {} vs {}", a.name, a.value, b.value);
        assert!(
            (a.std_error - b.std_error).abs() <= 1e-6 * a.std_error,
            "{}: {} vs {}",
            a.name,
            a.std_error,
            b.std_error
        );
    }
    assert!(big.untrusted_codes().is_empty() == one.untrusted_codes().is_empty());
}

#[test]
fn logs_of_different_motors_cannot_be_fitted_jointly() {
    // Logs no longer carry n_p: a joint fit is of one motor by construction, with one
    // `pole_pairs` option, which the options cannot be built without; 0 is the error naming
    // n_p.
    let (a, b) = (sample(), sample().renamed("second"));
    let err = fit_pmsm(&[a, b], &PmsmFitOptions::new(0)).unwrap_err();
    assert!(matches!(err.domain(), Some(PmsmError::InvalidPolePairs { n_p: 0 })), "{err:?}");
    assert!(err.to_string().contains("n_p"), "{err}");
}

#[test]
fn no_speed_makes_the_least_squares_start_fail_clearly() {
    let n = 200;
    let s = Signals {
        u_d: (0..n).map(|k| (k % 7) as f64).collect(),
        u_q: (0..n).map(|k| (k % 5) as f64).collect(),
        i_d: (0..n).map(|k| (k % 3) as f64).collect(),
        i_q: (0..n).map(|k| (k % 2) as f64).collect(),
        w_m: vec![0.0; n],
        ..Default::default()
    };
    let e = s.into_experiment("standstill", 1e-4).unwrap();
    let err = fit_pmsm(&[e], &pmsm_options(4)).unwrap_err();
    assert!(err.to_string().contains("k_e"), "{err}");
}

#[test]
fn model_rejects_invalid_parameter_values_by_name() {
    let m = PmsmSpm::new(4, VoltageHold::Dq);
    let inputs = m.prepare(&sample()).unwrap();
    let err = m.coefficients(&[0.9, 0.0, 0.5], &inputs).unwrap_err();
    assert!(err.to_string().contains("l_s"), "{err}");
}

/// Runs the `greybox` binary from the repository root.
#[cfg(feature = "cli")]
pub(crate) fn greybox(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_greybox"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap()
}

#[test]
#[cfg(feature = "cli")]
fn cli_reports_bad_input_without_panicking() {
    for (args, culprit) in [
        (vec!["fit", "no/such/file.csv", "-p", "4"], "no/such/file.csv"),
        (vec!["fit", "data/sample.csv.gz", "-p", "0"], "pole pairs"),
        (vec!["fit", "data/sample.csv.gz", "-p", "4", "--col-ud", "u_d_missing"], "u_d_missing"),
        (vec!["fit", "data/sample.csv.gz", "-p", "4", "--start", "1,2"], "start"),
        (vec!["fit", "data/sample.csv.gz", "-p", "4", "--weighting", "low-speed:-5"], "corner speed"),
        (vec!["fit", "data/sample.csv.gz", "-p", "4", "--precision", "r_s=-1%"], "expected off or NAME=X%"),
        (vec!["fit", "data/sample.csv.gz", "-p", "4", "--precision", "=1%"], "`=1%`"),
        (vec!["fit", "data/sample.csv.gz", "-p", "4", "--method", "ls", "--precision", "off"], "--precision"),
        (vec!["fit", "data/sample.csv.gz", "-p", "4", "--precision", "R_s=1%"], "no parameter `R_s`"),
    ] {
        let out = greybox(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
        assert!(err.contains(culprit), "{args:?}: expected `{culprit}` in: {err}");
    }
}

#[test]
#[cfg(feature = "cli")]
fn cli_fit_prints_a_table_and_writes_the_json_report() {
    let json = crate::common::TempFile::new("cli", "report.json");
    let out = greybox(&["fit", "data/sample.csv.gz", "-p", "4", "--json", json.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8_lossy(&out.stdout);
    for word in ["r_s", "l_s", "k_e", "k_t", "psi_f", "95 % interval", "converged"] {
        assert!(table.contains(word), "table lacks {word}:\n{table}");
    }
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    std::fs::remove_file(&json).ok();
    assert_eq!(v["model"], "pmsm_spm");
    let names: Vec<&str> =
        v["parameters"].as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["r_s", "l_s", "k_e"]);
    for p in v["parameters"].as_array().unwrap() {
        for key in ["unit", "value", "std_error", "ci95", "error_index_percent", "fixed"] {
            assert!(!p[key].is_null(), "parameter lacks {key}: {p}");
        }
        assert_eq!(p["ci95"].as_array().unwrap().len(), 2);
    }
    let derived: Vec<&str> =
        v["derived"].as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap()).collect();
    assert_eq!(derived, ["k_t", "psi_f", "k_t_rms", "k_v", "k_m"]);
    for key in ["fit_percent", "rms_residual", "loss", "aic", "bic"] {
        assert!(!v["fit"][key].is_null(), "fit lacks {key}");
    }
    assert_eq!(v["solver"]["name"], "lm");
    assert_eq!(v["solver"]["success"], true);
    assert!(v["solver"]["iterations"].as_u64().unwrap() > 0);
    assert!(v["solver"]["termination"].is_string());
    for key in ["read_s", "fit_s", "total_s"] {
        assert!(v["timing"][key].as_f64().unwrap() >= 0.0, "timing lacks {key}");
    }
    // A prediction-error fit times its solver alone, a share of the fit.
    let solve_s = v["timing"]["solve_s"].as_f64().expect("a prediction-error fit has solve_s");
    assert!(solve_s > 0.0 && solve_s <= v["timing"]["fit_s"].as_f64().unwrap(), "{}", v["timing"]);
}

#[test]
fn a_sample_dropped_late_in_a_long_log_is_named_by_its_row() {
    let n = 20_000;
    let mut t: Vec<f64> = (0..=n).map(|k| k as f64 * 1e-4).collect();
    t.remove(15_000);
    let s = |v: f64| vec![v; n];
    let signals =
        Signals { u_d: s(1.0), u_q: s(1.0), i_d: s(0.0), i_q: s(0.0), w_m: s(0.0), ..Default::default() };
    let err = Experiment::try_from_time("dropped", "t", &t, signals.clone().into_channels()).unwrap_err();
    match &err {
        Error::NonUniformTime { row, column, .. } => {
            assert_eq!((*row, column.as_str()), (15_000, "t"), "{err}")
        }
        other => panic!("{other:?}"),
    }
    // A decreasing time stamp is named too.
    let mut t2: Vec<f64> = (0..n).map(|k| k as f64 * 1e-4).collect();
    t2[700] = t2[698];
    let err = Experiment::try_from_time("backwards", "t", &t2, signals.into_channels()).unwrap_err();
    assert!(matches!(err, Error::NonUniformTime { row: 700, .. }), "{err:?}");
}

/// A standard column under another name: the error gives the flag with the header's own
/// name (`--col-t "Time [s]"`), exit 2.
#[test]
#[cfg(feature = "cli")]
fn a_renamed_column_gets_the_flag_that_reads_it() {
    let path = crate::common::TempFile::new("renamed", "log.csv");
    let rows: String = (0..40).map(|k| format!("{},1,1,1,1,1\n", k as f64 * 1e-4)).collect();
    std::fs::write(&path, format!("Time [s],ud,uq,id,iq,Speed (rad/s)\n{rows}")).unwrap();
    let out = greybox(&["fit", path.to_str().unwrap(), "-p", "4"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--col-t \"Time [s]\""), "{err}");
    let out = greybox(&["fit", path.to_str().unwrap(), "-p", "4", "--col-t", "Time [s]"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--col-w \"Speed (rad/s)\""), "{err}");
    std::fs::remove_file(&path).ok();
}

/// A non-finite value names the file as the parse errors do, not only the row.
#[test]
#[cfg(feature = "cli")]
fn a_non_finite_value_names_its_file() {
    let path = crate::common::TempFile::new("nan", "log.csv");
    let rows: String = (0..40)
        .map(|k| format!("{},{},1,1,1,1\n", k as f64 * 1e-4, if k == 5 { "nan" } else { "1" }))
        .collect();
    std::fs::write(&path, format!("t,ud,uq,id,iq,w_m\n{rows}")).unwrap();
    let out = greybox(&["fit", path.to_str().unwrap(), "-p", "4"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(path.to_str().unwrap()) && err.contains("row 5"), "{err}");
    std::fs::remove_file(&path).ok();
}

/// `--precision` on the dynamic fit of the shipped log: its estimates are known to far
/// better than 0.5 % (exit 0), and to less than a thousandth of a percent of r_s, which is
/// stated as the reason for exit 3.
#[test]
#[cfg(feature = "cli")]
fn a_stated_accuracy_the_dynamic_fit_misses_is_exit_3() {
    let out = greybox(&["fit", "data/sample.csv.gz", "-p", "4", "--precision", "r_s=0.5%,k_e=0.05%", "-q"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let out = greybox(&["fit", "data/sample.csv.gz", "-p", "4", "--precision", "r_s=1e-7"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(3), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        text.contains("[imprecise]") && text.contains("r_s known to ±") && !text.contains("k_e known"),
        "{text}"
    );
}
