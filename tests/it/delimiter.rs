//! `--delimiter` and [`Delimiter`]: a semicolon, tab or pipe log reads (and fits) bit for
//! bit as the comma log it was made from; bad values are refused naming the flag; a
//! semicolon log read with the default comma fails with an error suggesting
//! `--delimiter ';'`.

use std::io::Read;

use greybox::data::{Delimiter, ReadLimits, Table};
use greybox::pmsm::{CsvOptions, read_log};
use proptest::prelude::*;

use super::csv_reader::{gzip, limits, read_table, temp_path, text, wanted};

/// The shipped sample log as comma-separated text.
fn sample_text() -> Vec<u8> {
    let mut text = Vec::new();
    let raw = std::fs::File::open("data/sample.csv.gz").unwrap();
    flate2::read::GzDecoder::new(raw).read_to_end(&mut text).unwrap();
    text
}

fn with(text: &[u8], d: u8) -> Vec<u8> {
    text.iter().map(|&b| if b == b',' { d } else { b }).collect()
}

/// `text` written to a fresh file (gzip-compressed if asked).
fn file(text: &[u8], gz: bool) -> crate::common::TempFile {
    let path = temp_path(if gz { "csv.gz" } else { "csv" });
    std::fs::write(&path, if gz { gzip(text) } else { text.to_vec() }).unwrap();
    path
}

fn read(
    text: &[u8],
    gz: bool,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    d: Delimiter,
) -> Result<Table, String> {
    let path = file(text, gz);
    let t = read_table(&path, wanted, limits, d).map(|t| Table { name: String::new(), ..t });
    std::fs::remove_file(&path).ok();
    let stem = path.file_name().unwrap().to_string_lossy().split('.').next().unwrap().to_string();
    t.map_err(|e| e.to_string().replace(&*path.to_string_lossy(), "LOG").replace(&stem, "LOG"))
}

fn bits(e: &greybox::data::Experiment) -> Vec<Vec<u64>> {
    e.channels().iter().map(|c| c.values.iter().map(|x| x.to_bits()).collect()).collect()
}

#[test]
fn semicolon_tab_and_pipe_logs_read_bit_for_bit_as_the_comma_log() {
    let text = sample_text();
    let comma = file(&text, false);
    let want = read_log(&comma, &CsvOptions::default()).unwrap();
    for (d, gz) in [(Delimiter::SEMICOLON, false), (Delimiter::TAB, true), (Delimiter::PIPE, false)] {
        let path = file(&with(&text, d.byte()), gz);
        let got = read_log(&path, &CsvOptions { delimiter: d, ..CsvOptions::default() }).unwrap();
        assert_eq!(bits(&got), bits(&want), "{d}");
        assert_eq!(got.h().to_bits(), want.h().to_bits(), "{d}");
        std::fs::remove_file(&path).ok();
    }
    std::fs::remove_file(&comma).ok();
}

/// The estimates of `greybox fit` on the sample, as JSON values.
#[cfg(feature = "cli")]
fn estimates(log: &std::path::Path, extra: &[&str]) -> Vec<serde_json::Value> {
    let args = [&["fit", log.to_str().unwrap(), "-p", "4", "-q", "--json", "-"], extra].concat();
    let out = super::errors::greybox(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    v["parameters"].as_array().unwrap().iter().map(|p| p["value"].clone()).collect()
}

#[test]
#[cfg(feature = "cli")]
fn semicolon_and_tab_logs_fit_to_the_same_estimates() {
    let text = sample_text();
    let comma = file(&text, false);
    let want = estimates(&comma, &[]);
    assert!(want.len() >= 3 && want.iter().all(serde_json::Value::is_f64), "{want:?}");
    for (flag, d) in [(";", b';'), ("tab", b'\t'), ("\\t", b'\t')] {
        let path = file(&with(&text, d), false);
        assert_eq!(estimates(&path, &["--delimiter", flag]), want, "--delimiter {flag}");
        std::fs::remove_file(&path).ok();
    }
    std::fs::remove_file(&comma).ok();
}

#[test]
#[cfg(feature = "cli")]
fn bad_delimiters_are_refused_naming_the_flag() {
    for cmd in ["fit", "validate", "track"] {
        for bad in [";;", "é", "\"", "\n", "space", "", "x"] {
            let out = super::errors::greybox(&[cmd, "--delimiter", bad, "data/sample.csv.gz"]);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{cmd} {bad:?}: {err}");
            assert!(err.contains("--delimiter") && err.contains("`;`"), "{cmd} {bad:?}: {err}");
            assert!(!err.contains("panicked"), "{err}");
        }
    }
}

#[test]
fn a_semicolon_log_read_with_commas_suggests_the_delimiter() {
    let text = sample_text();
    for (d, hint) in [(b';', "--delimiter ';'"), (b'\t', "--delimiter 'tab'")] {
        let path = file(&with(&text, d), false);
        let err = read_log(&path, &CsvOptions::default()).unwrap_err().to_string();
        assert!(err.contains(hint) && err.contains("line 1"), "{err}");
        #[cfg(feature = "cli")]
        {
            let out = super::errors::greybox(&["fit", path.to_str().unwrap(), "-p", "4", "-q"]);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success() && stderr.contains(hint), "{stderr}");
        }
        std::fs::remove_file(&path).ok();
    }
    // A one-field header without another delimiter is still a missing column.
    let err =
        read(b"time\n0\n", false, &[("t", true)], &ReadLimits::default(), Delimiter::COMMA).unwrap_err();
    assert!(err.contains("missing column `t`"), "{err}");
    // And a semicolon header is fine when the delimiter is `;`.
    let t =
        read(b"t;x\n0;1\n", false, &[("t", true), ("x", true)], &ReadLimits::default(), Delimiter::SEMICOLON);
    assert_eq!(t.unwrap().columns, vec![Some(vec![0.0]), Some(vec![1.0])]);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Any log-like text with its commas turned into `;` or `|` reads with that delimiter
    /// as the text reads with `,`: the same table, or the same error (cells quoted in it
    /// turned back, in both).
    #[test]
    fn other_delimiters_read_as_commas(
        text in text(), gz in any::<bool>(), wanted in wanted(), limits in limits(), pipe in any::<bool>()
    ) {
        let d = if pipe { Delimiter::PIPE } else { Delimiter::SEMICOLON };
        // The generated cells hold no `;` or `|`: any in a message is the message's own.
        let back = |e: String| e.replace(d.byte() as char, ",");
        let want = read(&text, gz, &wanted, &limits, Delimiter::COMMA).map_err(back);
        let got = read(&with(&text, d.byte()), gz, &wanted, &limits, d).map_err(back);
        prop_assert_eq!(got, want);
    }
}
