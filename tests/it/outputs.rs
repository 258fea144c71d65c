//! Outputs all or nothing (issue: no lost file): outputs that are inputs or each other are
//! refused with exit 2, a full or closed stdout is an error or quiet (never a panic),
//! interrupted and killed runs leave no temporary and no half-written output.
#![cfg(feature = "cli")]

use crate::common::TempDir;
use crate::errors::greybox;
use std::path::Path;
use std::process::{Command, Stdio};

fn temp_dir(name: &str) -> TempDir {
    TempDir::new(&format!("outputs-{name}"))
}

fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(::greybox::data::TEMPORARY_PREFIX))
        .collect()
}

/// The binary run with `args`, its output discarded.
fn quiet(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_greybox"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `validate --json` over its `--params`, two outputs in one file: exit 2 before any work,
/// the report untouched.
#[test]
fn an_output_over_an_input_or_another_output_is_refused() {
    let dir = temp_dir("refuse");
    let p = dir.join("p.json");
    assert_eq!(
        greybox(&["fit", "data/sample.csv.gz", "-p", "4", "-q", "--json", s(&p)]).status.code(),
        Some(0)
    );
    let before = std::fs::read(&p).unwrap();
    let out = greybox(&["validate", "data/sample.csv.gz", "--params", s(&p), "--json", s(&p)]);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("is an input"));
    assert_eq!(std::fs::read(&p).unwrap(), before, "the fit report was replaced");
    let a = dir.join("a.json");
    let out = greybox(&["fit", "data/sample.csv.gz", "-p", "4", "-q", "--json", s(&a), "--plot", s(&a)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("also the output of --json"));
    assert!(!a.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A full stdout is an error (exit 1, named), a reader that goes away is quiet; neither
/// panics, for the report, the JSON on stdout and the completions.
#[test]
fn a_full_or_closed_stdout_never_panics() {
    let full = Path::new("/dev/full");
    for args in [
        vec!["fit", "data/sample.csv.gz", "-p", "3"],
        vec!["fit", "data/sample.csv.gz", "-p", "4", "--json", "-"],
        vec!["completions", "bash"],
    ] {
        if full.exists() {
            let out = Command::new(env!("CARGO_BIN_EXE_greybox"))
                .args(&args)
                .current_dir(env!("CARGO_MANIFEST_DIR"))
                .stdout(std::fs::OpenOptions::new().write(true).open(full).unwrap())
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
            assert!(err.contains("cannot write stdout") && !err.contains("panicked"), "{args:?}: {err}");
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_greybox"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked") && out.status.code().is_some_and(|c| c != 101), "{args:?}: {err}");
    }
}

/// Fits with `--json --residuals --plot` killed (SIGKILL) or terminated (SIGTERM) at
/// random moments: a terminated run removes its temporaries itself; a killed one's are
/// removed by the next run in the folder; every output present is whole (the JSON parses,
/// the plot ends its SVG, the residual CSV has its header and full rows).
#[test]
fn killed_and_terminated_runs_leave_no_temporary_and_no_half_file() {
    let dir = temp_dir("kill");
    let (json, plot, res) = (dir.join("r.json"), dir.join("r.svg"), dir.join("r.csv"));
    let args = [
        "fit",
        "data/sample.csv.gz",
        "-p",
        "4",
        "-q",
        "--json",
        s(&json),
        "--plot",
        s(&plot),
        "--residuals",
        s(&res),
    ];
    let whole = || {
        if json.exists() {
            let _: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        }
        if plot.exists() {
            assert!(std::fs::read_to_string(&plot).unwrap().trim_end().ends_with("</svg>"));
        }
        if res.exists() {
            let text = std::fs::read_to_string(&res).unwrap();
            let widths: Vec<usize> = text.lines().map(|l| l.split(',').count()).collect();
            assert!(widths.iter().all(|w| *w == widths[0]), "a residual row is cut");
        }
    };
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    for round in 0..40 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let child = quiet(&args);
        std::thread::sleep(std::time::Duration::from_micros(seed % 150_000));
        let signal = if round % 2 == 0 { "-KILL" } else { "-TERM" };
        let _ = Command::new("kill").args([signal, &child.id().to_string()]).status();
        let mut child = child;
        let _ = child.wait();
        whole();
    }
    // The next run sweeps what killed runs left and writes whole outputs.
    let out = greybox(&args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    whole();
    assert!(json.exists() && plot.exists() && res.exists());
    assert_eq!(temporaries(&dir), Vec::<String>::new());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Terminated runs alone (no kill before them) leave no temporary.
#[test]
fn a_terminated_run_removes_its_temporaries() {
    let dir = temp_dir("term");
    let (json, res) = (dir.join("r.json"), dir.join("r.csv"));
    let args = ["fit", "data/sample.csv.gz", "-p", "4", "-q", "--json", s(&json), "--residuals", s(&res)];
    for delay_ms in [0u64, 20, 40, 60, 80, 100, 120] {
        let mut child = quiet(&args);
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = Command::new("kill").args(["-TERM", &child.id().to_string()]).status();
        let _ = child.wait();
        assert_eq!(temporaries(&dir), Vec::<String>::new(), "after SIGTERM at {delay_ms} ms");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
