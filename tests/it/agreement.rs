//! Reports and plots agree with each other and with the log (trust issue): one residual
//! figure wherever it appears, the fit's own predictor and counted samples in the plot and
//! the residual export, and the observer plot's truth following the plant.
#![cfg(feature = "cli")]

use crate::common::TempDir;
use crate::errors::greybox;
use std::path::PathBuf;

fn temp_dir(name: &str) -> TempDir {
    TempDir::new(&format!("agree-{name}"))
}

/// A dead-time-mask fit of an exact PWM-free log with a dead-time voltage: the report's rms
/// residual, the residual export's counted residuals and the plot's σ are one figure (the
/// masked periods, whose one-step errors are amperes, are in none of them).
#[test]
fn a_masked_fit_reports_plots_and_exports_one_residual() {
    let dir = temp_dir("mask");
    let (log, json, csv, svg) =
        (dir.join("dt.csv"), dir.join("f.json"), dir.join("r.csv"), dir.join("f.svg"));
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let out = greybox(&[
        "simulate",
        "--scenario",
        "exp3",
        "--duration",
        "2",
        "--set",
        "inverter.v_dt=6",
        "-o",
        &s(&log),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = greybox(&[
        "fit",
        &s(&log),
        "-p",
        "4",
        "-q",
        "--voltage",
        "reference",
        "--dead-time",
        "estimate",
        "--dead-time-mask",
        "auto",
        "--json",
        &s(&json),
        "--residuals",
        &s(&csv),
        "--plot",
        &s(&svg),
    ]);
    assert!(matches!(out.status.code(), Some(0 | 3)), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let fit = &v["fit"];
    assert_eq!(fit["horizon"].as_u64(), Some(1), "{fit}");
    let counted = fit["counted"].as_u64().expect("counted samples reported") as usize;
    let n = fit["samples"].as_u64().unwrap() as usize;
    assert!(counted > 100 && counted < n, "{counted} of {n}");
    // The export: every sample, a counted flag, the counted residuals' rms the report's.
    let mut r = csv::Reader::from_path(&csv).unwrap();
    let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (id_res, flag) = (col("id_residual"), col("counted"));
    let (mut sum, mut k, mut rows, mut all) = (0.0, 0usize, 0usize, 0.0f64);
    for rec in r.records() {
        let rec = rec.unwrap();
        let e: f64 = rec[id_res].parse().unwrap();
        rows += 1;
        all = all.max(e.abs());
        if &rec[flag] == "1" {
            sum += e * e;
            k += 1;
        }
    }
    // The export has every sample; the first (the initial state, no residual in the fit)
    // may count there besides the fit's.
    assert!(
        rows >= n && (counted..=counted + 1).contains(&k),
        "rows {rows} for {n}, counted {k} for {counted}"
    );
    let rms = (sum / k as f64).sqrt();
    let reported = fit["rms_residual"][0].as_f64().unwrap();
    assert!((rms - reported).abs() <= 1e-6 * reported.max(1e-300), "export {rms:e}, report {reported:e}");
    // An exact log: the counted residual is rounding, far below the masked periods' errors.
    assert!(reported < 1e-6 && all > 1e3 * reported, "report {reported:e}, largest residual {all:e}");
    // The plot says the same σ (five significant digits, in pA/nA/…) and names the predictor.
    let plot = std::fs::read_to_string(&svg).unwrap();
    assert!(plot.contains("1-step prediction"), "the plot does not name the predictor");
    let sigma = plot.split("σ = ").nth(1).and_then(|t| t.split('<').next()).unwrap().to_string();
    let (num, unit) = sigma.split_once(' ').unwrap();
    let scale = match unit.trim().trim_end_matches('A') {
        "p" => 1e-12,
        "n" => 1e-9,
        "µ" | "u" => 1e-6,
        "m" => 1e-3,
        "" => 1.0,
        other => panic!("unit {other}"),
    };
    let plotted: f64 = num.parse::<f64>().unwrap() * scale;
    assert!((plotted - reported).abs() <= 1e-4 * reported, "plot σ {sigma}, report {reported:e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The observer plot of thesis Exp 1 (K_t ramps down from 5 to 7 s, R_s up from 9 to
/// 11 s) draws the plant's ramps as the truth, not its start values.
#[test]
fn the_track_plot_follows_a_time_varying_truth() {
    let dir = temp_dir("exp1");
    let (log, svg) = (dir.join("exp1.csv"), dir.join("exp1.svg"));
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let out = greybox(&["simulate", "--scenario", "exp1", "--duration", "12", "-o", &s(&log)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let truth: greybox::drive::Truth =
        serde_json::from_str(&std::fs::read_to_string(dir.join("exp1.truth.json")).unwrap()).unwrap();
    assert!(truth.time_varying);
    let out = greybox(&["track", &s(&log), "-p", "4", "--l-s", "5e-3", "-q", "--plot", &s(&svg)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let plot = std::fs::read_to_string(&svg).unwrap();
    let end = greybox::drive::plant_at(&truth.config, 12.0);
    let k_e_end = 1.5f64.sqrt() * f64::from(end.n_p) * end.psi_f;
    for (start, end, unit) in [(truth.k_e, k_e_end, "V s/rad"), (truth.start.r_s, end.r_s, "Ω")] {
        assert!((end - start).abs() > 0.05 * start, "the scenario ramps: {start} → {end}");
        let label = format!("truth {} → {} {unit}", fmt5(start), fmt5(end));
        assert!(plot.contains(&label), "no `{label}` in the plot");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Five significant digits, as the plot's legend writes a value.
fn fmt5(v: f64) -> String {
    let digits = (4 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

/// A log whose time column starts at 0.6 s (the bundled sample) keeps its own time in the
/// residual export, the fit plot's axis and the observer's trajectory.
#[test]
fn outputs_keep_the_logs_own_time() {
    use std::io::Read;
    let mut text = String::new();
    let sample = concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz");
    flate2::read::GzDecoder::new(std::fs::File::open(sample).unwrap()).read_to_string(&mut text).unwrap();
    let t0: f64 = text.lines().nth(1).unwrap().split(',').next().unwrap().parse().unwrap();
    assert!(t0 > 0.1, "the sample should start late: {t0}");
    let dir = temp_dir("t0");
    let (csv, svg, track) = (dir.join("r.csv"), dir.join("f.svg"), dir.join("t.json"));
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let out = greybox(&["fit", sample, "-p", "4", "-q", "--residuals", &s(&csv), "--plot", &s(&svg)]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let first: f64 =
        csv::Reader::from_path(&csv).unwrap().records().next().unwrap().unwrap()[0].parse().unwrap();
    assert_eq!(first, t0);
    let out = greybox(&["track", sample, "-p", "4", "--l-s", "4.5e-3", "-q", "--json", &s(&track)]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&track).unwrap()).unwrap();
    let t = v["trajectory"]["t"].as_array().unwrap();
    assert!((t[0].as_f64().unwrap() - t0).abs() < 1e-9, "{}", t[0]);
    let _ = std::fs::remove_dir_all(&dir);
}
