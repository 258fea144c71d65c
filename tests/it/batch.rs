//! `greybox fit --each DIR_OR_GLOB` (issue 17 item 2) on the built binary: three logs
//! simulated by `greybox simulate` with known, different parameters plus a broken one in a
//! temporary folder. Each good log is recovered to its own truth in the summary CSV and
//! JSON, the broken one is `failed` with its error, the exit code says so, and the trend
//! plot is an SVG; all good logs exit 0; an untrusted fit is marked and exits 3; an empty
//! match and the flags a batch cannot honour are refused, naming the flag.
#![cfg(feature = "cli")]

use crate::common::TempDir;
use crate::errors::greybox;
use approx::{assert_relative_eq, relative_eq};
use serde_json::Value;
use std::path::Path;

/// The simulated logs: file name, r_s [Ω], ψ_f [V s] (l_s 5 mH, n_p 4 for all).
const LOGS: [(&str, f64, f64); 3] =
    [("a_cold.csv", 0.8, 0.09), ("b_warm.csv", 1.0, 0.10), ("c_hot.csv", 1.2, 0.11)];
/// The scenario's inductance [H].
const L_S: f64 = 5e-3;

/// A fresh temporary folder with the three simulated logs (and their truth JSONs, which
/// the folder expansion must skip).
fn logs_dir(tag: &str) -> TempDir {
    let d = TempDir::new(&format!("batch-{tag}"));
    for (name, r_s, psi_f) in LOGS {
        let (r, p) = (format!("motor.r_s={r_s}"), format!("motor.psi_f={psi_f}"));
        let o = d.join(name);
        let args = ["simulate", "--scenario", "exp3", "--duration", "0.5", "--set", &r, "--set", &p, "-o"];
        let out = greybox(&[&args[..], &[o.to_str().unwrap()]].concat());
        assert!(out.status.success(), "{}", stderr(&out));
    }
    d
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// K_e = √(3/2) n_p ψ_f (MODEL.md §2), n_p = 4.
fn k_e(psi_f: f64) -> f64 {
    1.5f64.sqrt() * 4.0 * psi_f
}

#[test]
fn batch_fits_each_log_and_reports_the_broken_one() {
    let dir = logs_dir("mixed");
    // A log with a non-number in its speed column: read error, line named.
    std::fs::write(dir.join("d_broken.csv"), "t,ud,uq,id,iq,w_m\n0,1,2,3,4,5\n0.0001,1,2,3,4,x\n").unwrap();
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    let (summary, trend) = (out_dir.join("summary"), out_dir.join("trend.svg"));
    // The thermal reference at b_warm's truth: its temperatures are T_0, the others' below
    // and above (winding) as their r_s.
    let thermal = ["--t0", "20", "--r-s0", "1.0", "--psi-f0", "0.1"];
    let args = ["fit", "--each", s(&dir), "-p", "4", "--summary", s(&summary), "--trend", s(&trend)];
    let out = greybox(&[&args[..], &thermal].concat());
    assert_eq!(out.status.code(), Some(4), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("d_broken.csv") && err.contains("cannot parse `x`"), "{err}");
    // The table: one row per log, in file-name order, the broken one failed.
    let table = String::from_utf8_lossy(&out.stdout).into_owned();
    let rows: Vec<&str> = table.lines().filter(|l| l.contains(" ok ") || l.contains(" failed ")).collect();
    assert_eq!(rows.len(), 4, "{table}");
    for (row, name) in rows.iter().zip(["a_cold", "b_warm", "c_hot", "d_broken"]) {
        assert!(row.starts_with(name), "{table}");
    }
    // JSON: each good log recovered to its own truth (noise-free logs: 1e-6 relative).
    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!((json["ok"].as_u64(), json["failed"].as_u64()), (Some(3), Some(1)));
    let logs = json["logs"].as_array().unwrap();
    assert_eq!(logs.len(), 4);
    for (log, (name, r_s, psi_f)) in logs.iter().zip(LOGS) {
        assert_eq!(log["status"], "ok", "{log}");
        assert!(log["log"].as_str().unwrap().ends_with(name));
        let p =
            |n: &str| log["parameters"].as_array().unwrap().iter().find(|p| p["name"] == n).unwrap().clone();
        for (n, truth) in [("r_s", r_s), ("l_s", L_S), ("k_e", k_e(psi_f))] {
            let v = p(n)["value"].as_f64().unwrap();
            assert!(relative_eq!(v, truth, max_relative = 1e-6), "{name} {n} = {v}, truth {truth}");
            assert!(p(n)["std_error"].as_f64().unwrap() > 0.0);
        }
        let k_t = log["derived"].as_array().unwrap().iter().find(|d| d["name"] == "k_t").unwrap();
        assert!(
            relative_eq!(k_t["value"].as_f64().unwrap(), 1.5 * 4.0 * psi_f, max_relative = 1e-6),
            "{k_t}"
        );
        assert!(log["fit_percent"].as_array().unwrap().iter().all(|f| f[1].as_f64().unwrap() > 99.9));
        assert!(log["hold"].is_string() && log["pole_pairs"] == 4);
    }
    let t_winding: Vec<f64> = logs[..3]
        .iter()
        .map(|l| {
            l["derived"].as_array().unwrap().iter().find(|d| d["name"] == "t_winding").unwrap()["value"]
                .as_f64()
                .unwrap()
        })
        .collect();
    assert!((t_winding[1] - 20.0).abs() < 1e-3 && t_winding[0] < 0.0 && t_winding[2] > 40.0, "{t_winding:?}");
    assert_eq!(logs[3]["status"], "failed");
    assert!(logs[3]["error"].as_str().unwrap().contains("cannot parse `x`"), "{}", logs[3]);
    // CSV: the same figures, one row per log, the failed one with its error and no values.
    let text = std::fs::read_to_string(out_dir.join("summary.csv")).unwrap();
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    let col =
        |name: &str| header.iter().position(|h| h == name).unwrap_or_else(|| panic!("{name}: {header:?}"));
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 4);
    for ((row, log), (_, r_s, psi_f)) in rows.iter().zip(logs).zip(LOGS) {
        assert_eq!(&row[col("status")], "ok");
        let num = |c: &str| row[col(c)].parse::<f64>().unwrap();
        // The interval columns are the JSON record's intervals to the bit (the CSV's cells
        // round-trip the record, which copies the fit's `ci95`).
        for (list, name, unit) in [("parameters", "r_s", "Ω"), ("derived", "k_t", "N m/A")] {
            let q = log[list].as_array().unwrap().iter().find(|q| q["name"] == name).unwrap();
            let ci: Vec<f64> = q["ci95"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            assert_eq!([num(&format!("{name}_low [{unit}]")), num(&format!("{name}_high [{unit}]"))], ci[..]);
            assert!(ci[0] <= q["value"].as_f64().unwrap() && q["value"].as_f64().unwrap() <= ci[1], "{q}");
        }
        assert_relative_eq!(num("r_s [Ω]"), r_s, max_relative = 1e-6);
        assert_relative_eq!(num("k_e [V s/rad]"), k_e(psi_f), max_relative = 1e-6);
        assert_relative_eq!(num("l_s [H]"), L_S, max_relative = 1e-6);
        assert!(num("r_s_se [Ω]") > 0.0);
        assert!(num("fit_id [%]") > 99.9 && num("psi_f [V s]") > 0.0 && num("t_magnet [°C]").is_finite());
    }
    assert_eq!(&rows[3][col("status")], "failed");
    assert!(rows[3][col("error")].contains("cannot parse `x`") && rows[3][col("r_s [Ω]")].is_empty());
    // The trend plot: an SVG naming the parameters and the logs.
    let svg = std::fs::read_to_string(&trend).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("r_s [Ω]") && svg.contains("k_e [mV s/rad]") && svg.contains("\nc_hot\n"), "trend");
    // Well-formed XML: every opened element closed.
    let opened = svg.matches('<').count() - svg.matches("</").count() - svg.matches("/>").count();
    assert_eq!(opened, svg.matches("</").count(), "unbalanced tags");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn batch_of_good_logs_exits_0_and_an_untrusted_fit_3() {
    let dir = logs_dir("good");
    let glob = format!("{}/*.csv", s(&dir));
    let out = greybox(&["fit", "--each", &glob, "-p", "4", "-q"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(out.stdout.is_empty(), "-q prints no table");
    assert!(stderr(&out).contains("3 ok, 0 untrusted, 0 failed"), "{}", stderr(&out));
    // One iteration from a far start: fitted, not converged, marked untrusted, exit 3.
    // The summary outside the logs' folder, which the glob would pick up next time.
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    let summary = out_dir.join("untrusted.json");
    let args = ["fit", "--each", &glob, "-p", "4", "--start", "2,0.01,0.3", "--max-iters", "1", "-q"];
    let out = greybox(&[&args[..], &["--summary", s(&summary)]].concat());
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    let json: Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    for log in json["logs"].as_array().unwrap() {
        assert_eq!((&log["status"], &log["converged"]), (&Value::from("untrusted"), &Value::from(false)));
        assert!(log["warnings"].as_array().unwrap().iter().any(|w| w["untrusted"] == true), "{log}");
    }
    let out = greybox(&[&args[..], &["--allow-unconverged"]].concat());
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn batch_refuses_an_empty_match_and_joint_fit_flags() {
    let dir = TempDir::new("batch-empty");
    std::fs::write(dir.join("notes.txt"), "not a log").unwrap();
    let empty_glob = format!("{}/*.parquet", s(&dir));
    for pattern in [s(&dir), empty_glob.as_str()] {
        let out = greybox(&["fit", "--each", pattern, "-p", "4"]);
        assert_eq!(out.status.code(), Some(2), "{pattern}");
        assert!(stderr(&out).contains("`--each`"), "{}", stderr(&out));
    }
    let bad_glob = format!("{}/[", s(&dir));
    assert!(stderr(&greybox(&["fit", "--each", &bad_glob, "-p", "4"])).contains("`--each`"));
    // Flags of one joint fit: refused by the command line (exit 2), naming them.
    for (extra, flag) in [
        (vec!["data/sample.csv.gz"], "[LOGS]"),
        (vec!["--per-log", "r_s"], "--per-log"),
        (vec!["--json", "x.json"], "--json"),
        (vec!["--plot", "x.svg"], "--plot"),
        (vec!["--residuals", "x.csv"], "--residuals"),
    ] {
        let out = greybox(&[&["fit", "--each", s(&dir), "-p", "4"][..], &extra].concat());
        assert_eq!(out.status.code(), Some(2), "{flag}");
        assert!(stderr(&out).contains("--each") && stderr(&out).contains(flag), "{}", stderr(&out));
    }
    // --method ls with --each, and the batch's outputs without it: named errors.
    let out = greybox(&["fit", "--each", s(&dir), "-p", "4", "--method", "ls"]);
    assert!(out.status.code() == Some(2) && stderr(&out).contains("`--method`"), "{}", stderr(&out));
    for flag in ["--summary", "--trend"] {
        let out = greybox(&["fit", "data/sample.csv.gz", "-p", "4", flag, "x"]);
        assert_eq!(out.status.code(), Some(2));
        assert!(stderr(&out).contains(&format!("`{flag}`")), "{}", stderr(&out));
    }
    // An output over an input log is refused before any fit.
    std::fs::write(dir.join("a.csv"), "t\n").unwrap();
    let out = greybox(&["fit", "--each", s(&dir), "-p", "4", "--summary", s(&dir.join("a.csv"))]);
    assert!(out.status.code() == Some(2) && stderr(&out).contains("`--summary`"), "{}", stderr(&out));
    let _ = std::fs::remove_dir_all(&dir);
}
