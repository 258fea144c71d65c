//! The command-line traps of issue 17 (items 5 and 6), one test each, on the built binary
//! with the shipped `data/sample.csv.gz` (n_p = 4, r_s 0.9 Ω, l_s 4.5 mH, k_e 0.5389 V s/rad)
//! or a simulated log in a temporary folder: comma lists, `--huber` and a following log,
//! the least-squares start clamped into `--bounds`, `--fix NAME=VALUE`, errors in the
//! words of the command line, duplicate logs, unique per-log names, shell completions, and
//! the report's table, Markdown and JSON forms.
#![cfg(feature = "cli")]

use crate::common::TempDir;
use crate::errors::greybox;
use serde_json::Value;
use std::io::{BufRead, Write};

const SAMPLE: &str = "data/sample.csv.gz";

/// A fresh temporary folder for one test.
fn temp_dir(tag: &str) -> TempDir {
    TempDir::new(&format!("traps-{tag}"))
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The JSON report printed by `--json -`.
fn json_of(args: &[&str]) -> (Option<i32>, Value) {
    let out = greybox(&[args, &["-q", "--json", "-"]].concat());
    let v = serde_json::from_str(&stdout(&out)).unwrap_or_else(|e| panic!("{e}: {}", stderr(&out)));
    (out.status.code(), v)
}

fn parameter<'a>(v: &'a Value, name: &str) -> &'a Value {
    v["parameters"].as_array().unwrap().iter().find(|p| p["name"] == name).unwrap()
}

/// `--col-i-abc Ia,Ib,Ic` (the form the help shows) takes the three names; a log whose
/// phase columns have exactly those names is read and fitted. Other comma lists alike.
#[test]
fn comma_lists_work_where_the_help_shows_them() {
    let dir = temp_dir("phases");
    let log = dir.join("phases.csv");
    // The sample's dq signals as phase quantities at θ_e = 4 θ_m (amplitude-invariant).
    let raw = std::fs::File::open(SAMPLE).unwrap();
    let lines = std::io::BufReader::new(flate2::read::GzDecoder::new(raw)).lines();
    let mut w = std::io::BufWriter::new(std::fs::File::create(&log).unwrap());
    writeln!(w, "t,w_m,theta_m,Ia,Ib,Ic,Ua,Ub,Uc").unwrap();
    let abc = |d: f64, q: f64, th: f64| {
        let (al, be) = (d * th.cos() - q * th.sin(), d * th.sin() + q * th.cos());
        let r = 3f64.sqrt() / 2.0;
        [al, -0.5 * al + r * be, -0.5 * al - r * be]
    };
    for line in lines.skip(1) {
        let f: Vec<f64> = line.unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        let (i, u) = (abc(f[3], f[4], 4.0 * f[6]), abc(f[1], f[2], 4.0 * f[6]));
        writeln!(w, "{},{},{},{},{},{},{},{},{}", f[0], f[5], f[6], i[0], i[1], i[2], u[0], u[1], u[2])
            .unwrap();
    }
    drop(w);
    let l = log.to_str().unwrap();
    let args =
        ["fit", l, "-p", "4", "-q", "--dq-from-phases", "--col-i-abc", "Ia,Ib,Ic", "--col-u-abc", "Ua,Ub,Uc"];
    let out = greybox(&args);
    assert!(matches!(out.status.code(), Some(0 | 3)), "{}", stderr(&out));
    // Two names are refused by the flag itself, naming it.
    let out = greybox(&["fit", l, "-p", "4", "--dq-from-phases", "--col-i-abc", "Ia,Ib"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--col-i-abc"), "{}", stderr(&out));
    // --fix and --per-log take comma lists too.
    let (code, v) = json_of(&["fit", SAMPLE, "-p", "4", "--fix", "r_s,k_e"]);
    assert_eq!(code, Some(0));
    assert!(parameter(&v, "r_s")["fixed"] == true && parameter(&v, "k_e")["fixed"] == true);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 44: a log whose columns are all named otherwise (`t,Id,Iq,Ud,Uq,speed_rpm`) took
/// seven runs, one per column and one for the unit. The first error now names every flag
/// the header calls for, `--speed-unit rpm` from the speed column's name among them, and
/// the command line it gives fits the log.
#[test]
fn one_error_names_every_renamed_column() {
    let dir = temp_dir("renamed");
    let log = dir.join("renamed.csv");
    let raw = std::fs::File::open(SAMPLE).unwrap();
    let lines = std::io::BufReader::new(flate2::read::GzDecoder::new(raw)).lines();
    let mut w = std::io::BufWriter::new(std::fs::File::create(&log).unwrap());
    writeln!(w, "t,Ud,Uq,Id,Iq,speed_rpm").unwrap();
    for line in lines.skip(1) {
        let f: Vec<f64> = line.unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        writeln!(w, "{},{},{},{},{},{}", f[0], f[1], f[2], f[3], f[4], f[5] * 30.0 / std::f64::consts::PI)
            .unwrap();
    }
    drop(w);
    let l = log.to_str().unwrap();
    let out = greybox(&["fit", l, "-p", "4", "-q"]);
    let err = stderr(&out);
    assert_ne!(out.status.code(), Some(0), "{err}");
    for flag in [
        "--col-ud \"Ud\"",
        "--col-uq \"Uq\"",
        "--col-id \"Id\"",
        "--col-iq \"Iq\"",
        "--col-w \"speed_rpm\"",
        "--speed-unit rpm",
    ] {
        assert!(err.contains(flag), "{flag}: {err}");
    }
    let given = [
        "--col-ud",
        "Ud",
        "--col-uq",
        "Uq",
        "--col-id",
        "Id",
        "--col-iq",
        "Iq",
        "--col-w",
        "speed_rpm",
        "--speed-unit",
        "rpm",
    ];
    let out = greybox(&[&["fit", l, "-p", "4", "-q"][..], &given[..]].concat());
    assert!(matches!(out.status.code(), Some(0 | 3)), "{}", stderr(&out));
    // The same in one flag, as the message also gives it; the per-column report identical.
    let one = "--columns \"ud=Ud,uq=Uq,id=Id,iq=Iq,w_m=speed_rpm\" --speed-unit rpm";
    assert!(err.contains(one), "{one}: {err}");
    let json = |extra: &[&str], name: &str| {
        let path = dir.join(name);
        let p = path.to_str().unwrap().to_string();
        let out = greybox(&[&["fit", l, "-p", "4", "-q", "--json", &p][..], extra].concat());
        assert!(matches!(out.status.code(), Some(0 | 3)), "{}", stderr(&out));
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        v.as_object_mut().unwrap().remove("timing");
        v
    };
    let columns = ["--columns", "ud=Ud,uq=Uq,id=Id,iq=Iq,w_m=speed_rpm", "--speed-unit", "rpm"];
    assert_eq!(json(&columns, "one.json"), json(&given, "flags.json"));
    // A name that is not standard, a key given twice and the flag beside a per-column one:
    // exit 2, each saying why.
    for (bad, says) in [
        (&["--columns", "Id=Id"][..], "not a standard column name; one of t, ud, uq, id"),
        (&["--columns", "id=Id,id=Iq"][..], "`id` is given twice"),
        (&["--columns", "id=Id", "--col-iq", "Iq"][..], "cannot be used with"),
        (&["--columns", "id="][..], "empty"),
    ] {
        let out = greybox(&[&["fit", l, "-p", "4", "-q"][..], bad].concat());
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
        assert!(stderr(&out).contains(says), "{bad:?}: {}", stderr(&out));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every standard column name of `--columns` sets the field whose default header it is.
#[test]
fn the_standard_column_names_are_the_defaults() {
    let defaults = greybox::pmsm::ColumnNames::default();
    for key in greybox::pmsm::ColumnNames::STANDARD {
        let mut names = defaults.clone();
        let column = names.column_mut(key).expect(key);
        assert_eq!(column, key);
        *column = "renamed".into();
        assert_ne!(names, defaults, "{key}");
    }
    assert!(defaults.clone().column_mut("Id").is_none());
}

/// `--huber 2.0 LOG` does not read `2.0` as a log: the error names the word and says to
/// write `--huber=2.0`, which works, as does `--huber` alone before a log.
#[test]
fn huber_never_swallows_a_log_path() {
    let out = greybox(&["fit", "--huber", "2.0", SAMPLE, "-p", "4", "-q"]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(err.contains("`2.0`") && err.contains("--huber=2.0"), "{err}");
    for flag in ["--huber=2.0", "--huber"] {
        let out = greybox(&["fit", flag, SAMPLE, "-p", "4", "-q"]);
        assert!(matches!(out.status.code(), Some(0 | 3)), "{flag}: {}", stderr(&out));
    }
}

/// A least-squares start outside `--bounds` is clamped into them with a note, not refused:
/// with the truth inside, the fit converges there (exit 0); with the truth outside, it
/// ends at the bound (exit 3, `parameter_at_bound`) instead of failing before the fit.
#[test]
fn least_squares_start_is_clamped_into_the_bounds() {
    // LS gives l_s = 4.5009 mH, above 4.5005 mH; the truth, 4.5000 mH, is inside.
    let (code, v) = json_of(&["fit", SAMPLE, "-p", "4", "--bounds", "l_s:0.001:0.0045005"]);
    assert_eq!(code, Some(0), "{v}");
    let l_s = parameter(&v, "l_s");
    assert_eq!(l_s["start"].as_f64().unwrap(), 0.0045005);
    assert!((l_s["value"].as_f64().unwrap() - 4.5e-3).abs() < 1e-8);
    let notes = v["pmsm_notes"].to_string();
    assert!(notes.contains("start of l_s") && notes.contains("outside its bounds"), "{notes}");
    // The example: r_s = 0.9 Ω lies below the bounds.
    let (code, v) = json_of(&["fit", SAMPLE, "-p", "4", "--bounds", "r_s:0.95:2"]);
    assert_eq!(code, Some(3));
    assert_eq!(parameter(&v, "r_s")["value"].as_f64().unwrap(), 0.95);
    assert!(v["warnings"].to_string().contains("parameter_at_bound"));
    // A start the user gave is theirs: outside the bounds it is still an error.
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--bounds", "r_s:0.95:2", "--start", "0.9,0.0045,0.54"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("r_s"));
}

/// `--fix r_s=0.9` holds r_s at 0.9 Ω exactly; `--fix r_s` still holds it at the start
/// (the least-squares estimate); a bad value is refused naming the flag.
#[test]
fn fix_at_a_given_value() {
    let (code, v) = json_of(&["fit", SAMPLE, "-p", "4", "--fix", "r_s=0.95"]);
    assert!(matches!(code, Some(0 | 3)));
    let r_s = parameter(&v, "r_s");
    assert_eq!((r_s["value"].as_f64(), r_s["fixed"].as_bool()), (Some(0.95), Some(true)));
    let (_, v) = json_of(&["fit", SAMPLE, "-p", "4", "--fix", "r_s"]);
    let r_s = parameter(&v, "r_s");
    assert_eq!(r_s["value"], r_s["start"]);
    assert!((r_s["value"].as_f64().unwrap() - 0.89996).abs() < 1e-4, "{r_s}");
    for bad in ["r_s=abc", "r_s=inf", "=1"] {
        let out = greybox(&["fit", SAMPLE, "-p", "4", "--fix", bad]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
        assert!(stderr(&out).contains("--fix"), "{bad}: {}", stderr(&out));
    }
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--fix", "l_d=0.004"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("`--fix`") && stderr(&out).contains("l_d"), "{}", stderr(&out));
}

/// Errors name the flag and the model as the user typed them, never the library's field
/// names (`per_experiment`, `fixed`) or its model names (`pmsm_spm`, `Spm`).
#[test]
fn errors_name_the_flag_and_the_model_as_typed() {
    for (args, flag) in [
        (vec!["--per-log", "x_s"], "`--per-log`"),
        (vec!["--start", "1,2"], "`--start`"),
        (vec!["--fix", "l_q"], "`--fix`"),
        (vec!["--bounds", "x:1:2"], "`--bounds`"),
    ] {
        let out = greybox(&[&["fit", SAMPLE, "-p", "4", "-q"][..], &args].concat());
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = stderr(&out);
        assert!(err.contains(flag), "{args:?}: {err}");
        for internal in ["per_experiment", "`fixed`", "`bounds`", "pmsm_spm", "Spm"] {
            assert!(!err.contains(internal), "{args:?}: {err}");
        }
    }
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--per-log", "x_s"]);
    assert!(stderr(&out).contains("--model spm"), "{}", stderr(&out));
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--model", "ipm", "--start", "1,2"]);
    assert!(stderr(&out).contains("ipm model"), "{}", stderr(&out));
}

/// `validate`, `track` and `simulate` name their own flags too, with the `--` the user
/// typed: the observer's gains, the inductance, the pole pairs, the scenario and the
/// outputs (`--json` for a report, `--output` for a simulated log).
#[test]
fn other_commands_name_their_flags() {
    let dir = temp_dir("flags");
    let missing = dir.join("no/such/folder/x.csv");
    let missing = missing.to_str().unwrap();
    let track = ["track", SAMPLE, "-p", "4"];
    let mras = ["track", SAMPLE, "-p", "4", "--estimator", "mras"];
    for (args, flag) in [
        ([&mras[..], &["--l-s", "4.5e-3", "--gamma-ke", "-1"]].concat(), "`--gamma-ke`"),
        ([&mras[..], &["--l-s", "4.5e-3", "--gamma-rs", "1"]].concat(), "`--gamma-rs`"),
        ([&track[..], &["--l-s", "-1"]].concat(), "`--l-s`"),
        ([&mras[..], &["--l-s", "4.5e-3", "--observer-gain", "-2"]].concat(), "`--observer-gain`"),
        // A gain of the MRAS with the Kalman filter (the default), and the filter's noise
        // with the MRAS.
        ([&track[..], &["--l-s", "4.5e-3", "--gamma-ke", "0.01"]].concat(), "`--gamma-ke`"),
        ([&mras[..], &["--l-s", "4.5e-3", "--current-noise", "0.01"]].concat(), "`--current-noise`"),
        (vec!["track", SAMPLE, "-p", "0", "--l-s", "4.5e-3"], "`--pole-pairs`"),
        ([&track[..], &["--l-s", "4.5e-3", "--json", SAMPLE]].concat(), "`--json`"),
        (vec!["validate", SAMPLE, "--params", SAMPLE, "--json", SAMPLE], "`--json`"),
        (vec!["simulate", "--scenario", "exp9", "-o", missing], "`--scenario`"),
        (vec!["simulate", "--scenario", "exp1", "-o", missing], "`--output`"),
    ] {
        let out = greybox(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: {err}");
    }
}

/// The same log given twice is refused, as typed and after resolving `..` (it would
/// shrink the standard errors by √2).
#[test]
fn duplicate_logs_are_refused() {
    for second in [SAMPLE, "./data/../data/sample.csv.gz"] {
        let out = greybox(&["fit", SAMPLE, second, "-p", "4", "-q"]);
        assert_eq!(out.status.code(), Some(2), "{second}");
        let err = stderr(&out);
        assert!(err.contains(second) && err.contains("√2"), "{err}");
    }
}

/// Per-log rows carry the shortest path suffix that tells the logs apart: `a/run.csv.gz`
/// and `b/run.csv.gz` give `r_s[a/run]` and `r_s[b/run]` (simulated logs).
#[test]
fn per_log_names_are_unique() {
    let dir = temp_dir("names");
    for sub in ["a", "b"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
        let o = dir.join(sub).join("run.csv");
        let out = greybox(&["simulate", "--scenario", "exp3", "--duration", "1", "-o", o.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    }
    let (a, b) = (dir.join("a/run.csv"), dir.join("b/run.csv"));
    let args = ["fit", a.to_str().unwrap(), b.to_str().unwrap(), "-p", "4", "--per-log", "r_s"];
    let out = greybox(&args);
    assert!(matches!(out.status.code(), Some(0 | 3)), "{}", stderr(&out));
    let table = stdout(&out);
    assert!(table.contains("r_s[a/run]") && table.contains("r_s[b/run]"), "{table}");
    let (_, v) = json_of(&args);
    let exps: Vec<&str> = v["experiments"].as_array().unwrap().iter().map(|e| e.as_str().unwrap()).collect();
    assert_eq!(exps, ["a/run", "b/run"]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `greybox completions bash|zsh|fish` print a script that knows the subcommands and flags.
#[test]
fn shell_completions() {
    for shell in ["bash", "zsh", "fish"] {
        let out = greybox(&["completions", shell]);
        assert_eq!(out.status.code(), Some(0), "{shell}: {}", stderr(&out));
        let s = stdout(&out);
        assert!(s.contains("greybox") && s.contains("per-log") && s.contains("simulate"), "{shell}");
    }
    assert_eq!(greybox(&["completions", "tcsh"]).status.code(), Some(2));
}

/// The table: engineering prefixes and units on every figure, aligned columns, the x0
/// rows under their own heading, the index legend, fixed parameters marked, the labelled
/// correlation matrix and the conventions in words (k_t per RMS ampere for an RMS log).
#[test]
fn report_table_reads_at_a_glance() {
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--fix", "k_e"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let t = stdout(&out);
    for want in [
        "mΩ",
        "mH",
        "index %: parametric error index",
        "initial state",
        "line-to-line RMS back-EMF per mechanical rad/s",
        "per ampere of peak phase current",
        "correlation of the free parameters",
        "µA",
        "A²",
    ] {
        assert!(t.contains(want), "missing {want:?}:\n{t}");
    }
    assert!(!t.contains("e0 ") && !t.contains("per RMS ampere"), "{t}");
    let k_e = t.lines().find(|l| l.trim_start().starts_with("k_e ")).unwrap();
    assert!(k_e.contains("fixed") && k_e.contains("mV s/rad"), "{k_e}");
    // Parameter rows: the unit column starts at the same character in every row.
    let rows: Vec<&str> = t.lines().skip_while(|l| *l != "parameters").skip(1).take(4).collect();
    let col = |l: &str| {
        l.chars()
            .collect::<Vec<_>>()
            .windows(3)
            .position(|w| w[0] == ' ' && w[1] == ' ' && "mµΩ".contains(w[2]))
    };
    let starts: Vec<Option<usize>> = rows[1..].iter().map(|l| col(l)).collect();
    assert!(starts.iter().all(|s| s.is_some() && *s == starts[0]), "{rows:#?}");
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--current-scale", "rms", "--allow-unconverged"]);
    assert!(stdout(&out).contains("per RMS ampere"), "{}", stdout(&out));
}

/// `--format markdown` prints pipe tables; `--format json` the JSON report, with the
/// correlation labels and output units added beside the fields scripts already read.
#[test]
fn report_formats() {
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--format", "markdown"]);
    let md = stdout(&out);
    assert!(md.contains("### parameters") && md.contains("| parameter | estimate |"), "{md}");
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--format", "json"]);
    let v: Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(v["correlation_names"], serde_json::json!(["r_s", "l_s", "k_e"]));
    assert_eq!(v["fit"]["output_units"], serde_json::json!(["A", "A"]));
    assert!(v["parameters"][0]["value"].is_f64() && v["fit"]["fit_percent"].is_array());
    let out = greybox(&["fit", SAMPLE, "-p", "4", "--method", "ls"]);
    let t = stdout(&out);
    assert!(t.contains("mΩ") && t.contains("ud") && t.contains(" V"), "{t}");
}

/// `-` reads the log from standard input (gzip or plain), named `stdin`, with the estimates
/// of the same log read from its file; `-` given twice is refused (stdin reads once).
#[test]
fn a_log_from_standard_input() {
    use std::process::{Command, Stdio};
    let (code, from_file) = json_of(&["fit", SAMPLE, "-p", "4"]);
    assert_eq!(code, Some(0));
    let run = |stdin: Stdio| {
        Command::new(env!("CARGO_BIN_EXE_greybox"))
            .args(["fit", "-", "-p", "4", "-q", "--json", "-"])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdin(stdin)
            .output()
            .unwrap()
    };
    let gz = std::fs::File::open(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(SAMPLE)).unwrap();
    let out = run(Stdio::from(gz));
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let from_stdin: Value = serde_json::from_str(&stdout(&out)).unwrap();
    for name in ["r_s", "l_s", "k_e"] {
        assert_eq!(parameter(&from_stdin, name)["value"], parameter(&from_file, name)["value"], "{name}");
    }
    assert!(stdout(&out).contains("stdin"), "the log is named stdin");
    let out = greybox(&["fit", "-", "-", "-p", "4"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("given twice"), "{}", stderr(&out));
}

/// A data error in a CSV log names the file and the line the user sees in an editor, not
/// only the 0-based data row (the trust issue: "row 298", file line 300, no file name).
#[test]
fn data_errors_name_the_file_and_its_line() {
    use std::io::Read;
    let dir = temp_dir("line");
    let mut text = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(SAMPLE).unwrap()).read_to_string(&mut text).unwrap();
    let mut lines: Vec<String> = text.lines().take(400).map(String::from).collect();
    // Line 300 of the file (data row 298): its ud not finite.
    let mut fields: Vec<&str> = lines[299].split(',').collect();
    fields[1] = "inf";
    lines[299] = fields.join(",");
    let path = dir.join("units.csv");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let out = greybox(&["fit", path.to_str().unwrap(), "-p", "4", "-q"]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("units.csv") && err.contains("line 300"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
