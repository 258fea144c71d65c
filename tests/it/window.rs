//! The time window (`--from/--to`), the time unit (`--time-unit`) and the split of a log at
//! the gaps of its time column (`--split-gaps`, `read_log_segments`), on logs cut from the
//! shipped `data/sample.csv.gz` (n_p = 4, r_s 0.9 Ω, l_s 4.5 mH, k_e 0.5389 V s/rad,
//! h = 100 µs, t from 0.6 s to 2.5999 s) into a temporary folder: the same rows and
//! bit-identical estimates as the files cut by hand, and every error naming its flag.
#![cfg(feature = "cli")]

use crate::common::TempDir;
use crate::errors::greybox;
use greybox::Error;
use greybox::data::TimeWindow;
use greybox::pmsm::{CsvOptions, TimeUnit, read_log, read_log_segments};
use serde_json::Value;
use std::io::BufRead;
use std::path::{Path, PathBuf};

const SAMPLE: &str = "data/sample.csv.gz";

/// A fresh temporary folder for one test.
fn temp_dir(tag: &str) -> TempDir {
    TempDir::new(&format!("window-{tag}"))
}

/// The sample's header and data lines.
fn sample() -> (String, Vec<String>) {
    let raw = std::fs::File::open(Path::new(env!("CARGO_MANIFEST_DIR")).join(SAMPLE)).unwrap();
    let mut lines = std::io::BufReader::new(flate2::read::GzDecoder::new(raw)).lines().map(Result::unwrap);
    let header = lines.next().unwrap();
    (header, lines.collect())
}

/// Writes `header` and `rows` to `dir/name`.
fn write(dir: &Path, name: &str, header: &str, rows: &[String]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
    p
}

fn time(row: &str) -> f64 {
    row.split(',').next().unwrap().parse().unwrap()
}

fn options() -> CsvOptions {
    CsvOptions { pole_pairs: Some(4), ..CsvOptions::default() }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `(exit code, stderr)` of a command line.
fn run(args: &[&str]) -> (Option<i32>, String) {
    let out = greybox(args);
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// The JSON report of `greybox fit ARGS -q --json -` (exit code 0).
fn fit(args: &[&str]) -> Value {
    let out = greybox(&[&["fit"], args, &["-p", "4", "-q", "--json", "-"]].concat());
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Each parameter's name, value and standard error, bit for bit.
fn estimates(v: &Value) -> Vec<(String, u64, u64)> {
    v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let bits = |k: &str| p[k].as_f64().unwrap().to_bits();
            (p["name"].as_str().unwrap().to_string(), bits("value"), bits("std_error"))
        })
        .collect()
}

fn value(v: &Value, name: &str) -> f64 {
    v["parameters"].as_array().unwrap().iter().find(|p| p["name"] == name).unwrap()["value"].as_f64().unwrap()
}

#[test]
fn a_window_keeps_exactly_its_rows_and_fits_as_the_file_cut_by_hand() {
    let dir = temp_dir("cut");
    let (header, rows) = sample();
    let (from, to) = (1.0, 1.5);
    // Both ends inclusive: 1.000000 and 1.500000 are rows of the sample.
    let kept: Vec<String> = rows.iter().filter(|r| (from..=to).contains(&time(r))).cloned().collect();
    assert_eq!(kept.len(), 5001);
    let whole = write(&dir, "whole.csv", &header, &rows);
    let cut = write(&dir, "cut.csv", &header, &kept);
    let window = TimeWindow { from: Some(from), to: Some(to) };
    let windowed = read_log(&whole, &CsvOptions { window, ..options() }).unwrap();
    let by_hand = read_log(&cut, &options()).unwrap();
    assert_eq!(windowed.len(), 5001);
    assert_eq!(windowed.renamed("x"), by_hand.renamed("x"));
    // One side open.
    let from_only =
        read_log(&whole, &CsvOptions { window: TimeWindow { from: Some(from), to: None }, ..options() });
    assert_eq!(from_only.unwrap().len(), rows.iter().filter(|r| time(r) >= from).count());
    let a = fit(&[s(&whole), "--from", "1", "--to", "1.5"]);
    let b = fit(&[s(&cut)]);
    assert_eq!(estimates(&a), estimates(&b));
    assert!((value(&a, "r_s") / 0.9 - 1.0).abs() < 1e-4, "{a}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn time_columns_in_ms_and_us_give_the_estimates_of_the_log_in_seconds() {
    let dir = temp_dir("unit");
    let (header, rows) = sample();
    // A step of 2^-13 s (122 µs) is exact in s, ms and µs, and so is its conversion.
    let with_time = |scale: f64| -> Vec<String> {
        rows.iter()
            .enumerate()
            .map(|(k, r)| format!("{},{}", k as f64 * scale / 8192.0, r.split_once(',').unwrap().1))
            .collect()
    };
    let logs: Vec<PathBuf> = [("s.csv", 1.0), ("ms.csv", 1e3), ("us.csv", 1e6)]
        .iter()
        .map(|&(name, scale)| write(&dir, name, &header, &with_time(scale)))
        .collect();
    let read =
        |p: &Path, time_unit| read_log(p, &CsvOptions { time_unit, ..options() }).unwrap().renamed("x");
    let in_s = read(&logs[0], TimeUnit::S);
    assert_eq!(in_s.h(), 1.0 / 8192.0);
    assert_eq!(read(&logs[1], TimeUnit::Ms), in_s);
    assert_eq!(read(&logs[2], TimeUnit::Us), in_s);
    // The sample's signals at another h than theirs: the fit warns (exit 3 without
    // --allow-unconverged), and its estimates must still be the same bit for bit.
    let any = "--allow-unconverged";
    let reference = estimates(&fit(&[s(&logs[0]), any]));
    assert_eq!(estimates(&fit(&[s(&logs[1]), "--time-unit", "ms", any])), reference);
    assert_eq!(estimates(&fit(&[s(&logs[2]), "--time-unit", "us", any])), reference);
    // The window is in seconds, after the unit.
    let a = read_log(
        &logs[1],
        &CsvOptions {
            time_unit: TimeUnit::Ms,
            window: TimeWindow { from: Some(0.5), to: Some(1.0) },
            ..options()
        },
    )
    .unwrap();
    assert_eq!(a.len(), 4097);
    // A column in ms read as s: h = 0.122 s, implausible; the message names the unit.
    let (code, err) = run(&["fit", s(&logs[1]), "-p", "4"]);
    assert_eq!(code, Some(1));
    assert!(err.contains("--time-unit ms"), "{err}");
    let (_, err) = run(&["fit", s(&logs[0]), "-p", "4", "--time-unit", "us"]);
    assert!(err.contains("--time-unit s"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_log_with_gaps_is_refused_or_split_into_segments_fitted_jointly() {
    let dir = temp_dir("gaps");
    let (header, rows) = sample();
    // Rows 0..5000 (0.6 s to 1.0999 s), a 5-row scrap 9000..9005 after a pause, then rows
    // 12000.. after another: three segments, the middle one too short to fit.
    let (first, scrap, second) = (&rows[..5000], &rows[9000..9005], &rows[12000..]);
    let gappy = write(&dir, "run.csv", &header, &[first, scrap, second].concat());
    let part1 = write(&dir, "part1.csv", &header, first);
    let part2 = write(&dir, "part2.csv", &header, second);
    // Without the flag: an error at the first gap that suggests the flag.
    let (code, err) = run(&["fit", s(&gappy), "-p", "4"]);
    assert_eq!(code, Some(1));
    assert!(err.contains("row 5000") && err.contains("--split-gaps"), "{err}");
    // A step back is a gap too.
    let back = write(&dir, "back.csv", &header, &[first, &rows[1000..3000]].concat());
    let (_, err) = run(&["fit", s(&back), "-p", "4"]);
    assert!(err.contains("row 5000") && err.contains("--split-gaps"), "{err}");
    // With it: the segments, the short one dropped with a warning naming its time span.
    let out = greybox(&["fit", s(&gappy), "-p", "4", "-q", "--split-gaps", "--json", "-"]);
    assert_eq!(out.status.code(), Some(0));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("t = 1.5 s to 1.5004 s") && err.contains("5 samples"), "{err}");
    let joint: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(joint["experiments"], serde_json::json!(["run#1", "run#2"]));
    for (name, truth) in [("r_s", 0.9), ("l_s", 4.5e-3), ("k_e", 0.5389)] {
        assert!((value(&joint, name) / truth - 1.0).abs() < 1e-3, "{name}: {joint}");
    }
    assert_eq!(estimates(&joint), estimates(&fit(&[s(&part1), s(&part2)])));
    // The library: the same segments as the files, the scrap listed.
    let log = read_log_segments(&gappy, &options()).unwrap();
    assert_eq!(log.name, "run");
    assert_eq!(log.experiments[0].clone().renamed("x"), read_log(&part1, &options()).unwrap().renamed("x"));
    assert_eq!(log.experiments[1].name(), "run#2");
    assert_eq!(log.experiments[1].clone().renamed("x"), read_log(&part2, &options()).unwrap().renamed("x"));
    assert_eq!((log.dropped.len(), log.dropped[0].samples, log.dropped[0].from), (1, 5, 1.5));
    // A log without gaps is one experiment under its own name, as read_log reads it.
    let one = read_log_segments(&part1, &options()).unwrap();
    assert_eq!(one.experiments, [read_log(&part1, &options()).unwrap()]);
    // validate takes the flag too and compares each segment.
    let report = dir.join("fit.json");
    let (code, err) = run(&["fit", s(&part1), "-p", "4", "-q", "--json", s(&report)]);
    assert_eq!(code, Some(0), "{err}");
    let out = greybox(&["validate", s(&gappy), "--params", s(&report), "--split-gaps"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("run#1:") && text.contains("run#2:"), "{text}");
    // track too, each segment its own run, named `#k` in the text and in the plot.
    let plot = dir.join("track.svg");
    let out =
        greybox(&["track", s(&gappy), "-p", "4", "--l-s", "4.5e-3", "--split-gaps", "--plot", s(&plot)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("run.csv#1:") && text.contains("run.csv#2:"), "{text}");
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.contains("run#1") && svg.contains("run#2"), "the track plot names no segment");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_error_of_the_window_and_the_split_names_its_flag() {
    let dir = temp_dir("errors");
    let (header, rows) = sample();
    let log = write(&dir, "log.csv", &header, &rows);
    let l = s(&log);
    let report = dir.join("fit.json");
    let (code, err) = run(&["fit", l, "-p", "4", "-q", "--json", s(&report)]);
    assert_eq!(code, Some(0), "{err}");
    let report_path = s(&report);
    for (args, flag, words) in [
        (&["--from", "nan"][..], "`--from`", "not a finite time"),
        (&["--to", "inf"][..], "`--to`", "not a finite time"),
        (&["--from", "2", "--to", "1"][..], "`--from`", "not before its end"),
        (&["--from", "1", "--to", "1"][..], "`--from`", "not before its end"),
        (&["--from", "1", "--to", "1.0001"][..], "`--from/--to`", "holds 2 samples"),
        (&["--from", "3"][..], "`--from/--to`", "holds 0 samples"),
        (&["--from", "-1", "--to", "0.6"][..], "`--from/--to`", "holds 1 samples"),
    ] {
        for command in ["fit", "validate", "track"] {
            let extra: &[&str] = match command {
                "fit" => &["-p", "4"],
                "validate" => &["--params", report_path],
                _ => &["-p", "4", "--l-s", "0.0045"],
            };
            let (code, err) = run(&[&[command, l], extra, args].concat());
            assert_eq!(code, Some(2), "{command} {args:?}: {err}");
            assert!(err.contains(flag) && err.contains(words), "{command} {args:?}: {err}");
        }
    }
    // Every segment too short: the split names its flag and the longest segment.
    let scraps: Vec<String> = (0..4).flat_map(|k| rows[k * 1000..k * 1000 + 6].to_vec()).collect();
    let bits = write(&dir, "bits.csv", &header, &scraps);
    let (code, err) = run(&["fit", s(&bits), "-p", "4", "--split-gaps"]);
    assert_eq!(code, Some(2));
    assert!(
        err.contains("`--split-gaps`") && err.contains("4 segments") && err.contains("longest has 6"),
        "{err}"
    );
    // The library names the options as fields.
    let bad = CsvOptions { window: TimeWindow { from: Some(1.0), to: Some(0.5) }, ..options() };
    assert!(matches!(read_log(&log, &bad), Err(Error::InvalidOption { option, .. }) if option == "from"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The columnar readers skip their streaming time check the same way: a Parquet log with a
/// pause is refused at the gap, or split at it.
#[cfg(feature = "parquet")]
#[test]
fn a_parquet_log_with_a_gap_splits_as_a_csv_log() {
    use greybox::data::{Channel, write_log};
    let dir = temp_dir("parquet");
    let e = read_log(Path::new(env!("CARGO_MANIFEST_DIR")).join(SAMPLE), &options()).unwrap();
    // A second time column with a 0.3 s pause before row 5000.
    let t: Vec<f64> =
        (0..e.len()).map(|k| 0.6 + k as f64 * 1e-4 + if k < 5000 { 0.0 } else { 0.3 }).collect();
    let path = dir.join("paused.parquet");
    write_log(&path, &e.with_channel(Channel::new("t_pause", "s", t)).unwrap(), "t").unwrap();
    let mut opts = options();
    opts.columns.t = "t_pause".into();
    let err = read_log(&path, &opts).unwrap_err();
    assert!(matches!(&err, Error::NonUniformTime { row: 5000, .. }), "{err:?}");
    assert!(err.to_string().contains("--split-gaps"), "{err}");
    let log = read_log_segments(&path, &opts).unwrap();
    let lengths: Vec<usize> = log.experiments.iter().map(|e| e.len()).collect();
    assert_eq!(lengths, [5000, 15000]);
    assert!(log.dropped.is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}
