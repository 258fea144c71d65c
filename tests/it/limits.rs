//! Robustness of the log reader against hostile or mistaken files: read limits enforced
//! while the file streams (gzip bombs stop early, in bounded memory), rows validated as
//! they arrive, cells quoted short, duplicate columns, and the plausibility limits on n_p
//! and h.

use crate::common::TempFile;
use greybox::pmsm::PmsmError;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use greybox::Error;
use greybox::data::{ColumnMap, CsvSpec, ReadLimits, read_csv};
use greybox::pmsm::{ColumnNames, CsvOptions, DqSource, read_log};

const HEADER: &str = "t,ud,uq,id,iq,w_m\n";

fn temp_path(tag: &str, ext: &str) -> TempFile {
    TempFile::new("limits", &format!("{tag}.{ext}"))
}

fn temp_file(tag: &str, contents: &[u8]) -> TempFile {
    let p = temp_path(tag, "csv");
    std::fs::write(&p, contents).expect("write temp file");
    p
}

/// A valid log of `n` rows every `h` [s].
fn rows(n: usize, h: f64) -> String {
    let mut s = String::from(HEADER);
    for k in 0..n {
        s.push_str(&format!("{:e},{},1,0.5,-0.25,10\n", k as f64 * h, 0.1 * k as f64));
    }
    s
}

fn read(p: &Path) -> greybox::Result<greybox::data::Experiment> {
    read_log(p, &CsvOptions { pole_pairs: Some(4), ..CsvOptions::default() })
}

/// Writes `head` then `block` repeated until `total` bytes, gzip-compressed, streaming
/// (the test holds one block in memory, never the file).
fn gzip_bomb(tag: &str, head: &[u8], block: &[u8], total: usize) -> TempFile {
    let p = temp_path(tag, "csv.gz");
    let file = std::io::BufWriter::new(std::fs::File::create(&p).unwrap());
    let mut gz = flate2::write::GzEncoder::new(file, flate2::Compression::best());
    gz.write_all(head).unwrap();
    let chunk: Vec<u8> = block.iter().copied().cycle().take((1 << 20) / block.len() * block.len()).collect();
    let mut written = head.len();
    while written < total {
        gz.write_all(&chunk).unwrap();
        written += chunk.len();
    }
    gz.finish().unwrap().flush().unwrap();
    p
}

/// Peak resident memory of this process [kB] (`VmHWM`), if the platform reports it.
fn vm_hwm_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Reads a bomb, reporting time and the peak memory before and after (a measurement, not
/// an assertion: other tests share the process).
fn read_bomb(p: &Path) -> Error {
    let size = std::fs::metadata(p).unwrap().len();
    let before = vm_hwm_kb();
    let start = Instant::now();
    let err = read(p).unwrap_err();
    eprintln!(
        "{}: {size} bytes gzip, rejected in {:.3} s, VmHWM {before:?} -> {:?} kB: {err}",
        p.display(),
        start.elapsed().as_secs_f64(),
        vm_hwm_kb()
    );
    err
}

const BOMB_BYTES: usize = 1_200_000_000;

#[test]
fn gzip_bomb_of_commas_stops_at_the_line_limit() {
    let p = gzip_bomb("commas", b"", b",", BOMB_BYTES);
    assert!(std::fs::metadata(&p).unwrap().len() < 2_000_000);
    let err = read_bomb(&p);
    assert!(
        matches!(&err, Error::LimitExceeded { line: 1, limit, max, .. } if limit == "max_line_bytes" && *max == 1 << 20),
        "{err:?}"
    );
    assert!(err.to_string().contains("line 1") && err.to_string().len() < 300, "{err}");
    std::fs::remove_file(p).ok();
}

#[test]
fn gzip_bomb_of_repeated_rows_stops_at_row_1() {
    // Deflate codes a match at distance 23 with 3 extra bits: 2.9 MB, not 1.2 MB.
    let p = gzip_bomb("rows", HEADER.as_bytes(), b"0.001,1,1,0.5,-0.25,10\n", BOMB_BYTES);
    assert!(std::fs::metadata(&p).unwrap().len() < 4_000_000);
    let err = read_bomb(&p);
    assert!(matches!(&err, Error::NonUniformTime { row: 1, column, .. } if column == "t"), "{err:?}");
    std::fs::remove_file(p).ok();
}

#[test]
fn a_long_data_line_is_named_by_its_line_before_it_is_buffered() {
    // 10 good rows, then a 20-million-character cell: line 12 (the header is line 1).
    let mut text = rows(10, 1e-3).into_bytes();
    text.extend_from_slice(b"0.01,1,");
    text.extend(std::iter::repeat_n(b'x', 20_000_000));
    text.extend_from_slice(b",0,0,10\n");
    let p = temp_file("long-line", &text);
    let err = read(&p).unwrap_err();
    assert!(matches!(&err, Error::LimitExceeded { line: 12, .. }), "{err:?}");
    assert!(err.to_string().len() < 300, "{err}");
    // Raised, the limit lets the line through to the parser, whose error quotes the cell
    // short with its full length.
    let limits = ReadLimits { max_line_bytes: 1 << 26, ..ReadLimits::default() };
    let err = read_log(&p, &CsvOptions { pole_pairs: Some(4), limits, ..CsvOptions::default() }).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, Error::Csv { line: 12, .. }), "{msg}");
    assert!(msg.contains("…") && msg.contains("20000000 bytes") && msg.len() < 300, "{msg}");
    std::fs::remove_file(p).ok();
}

#[test]
fn a_quoted_field_spanning_many_short_lines_counts_as_one_line() {
    // A record may span lines inside quotes: 2 MB of short lines in one quoted cell.
    let mut text = rows(5, 1e-3).into_bytes();
    text.extend_from_slice(b"0.005,\"");
    text.extend("a\n".repeat(1_000_000).bytes());
    text.extend_from_slice(b"\",1,0,0,10\n");
    let p = temp_file("quoted-lines", &text);
    let err = read(&p).unwrap_err();
    assert!(matches!(&err, Error::LimitExceeded { limit, .. } if limit == "max_line_bytes"), "{err:?}");
    std::fs::remove_file(p).ok();
    // Quoted header names and `""` escapes read as before.
    let text = rows(20, 1e-3).replace(HEADER, "\"t\",\"ud\",uq,id,iq,w_m,\"say \"\"hi\"\"\"\n");
    let text = text.replace(",10\n", ",10,\"a,\"\"b\"\"\"\n");
    let p = temp_file("quoted-header", text.as_bytes());
    assert_eq!(read(&p).unwrap().len(), 20);
    std::fs::remove_file(p).ok();
}

#[test]
fn a_long_cell_is_quoted_to_80_characters() {
    let cell = "x".repeat(100_000);
    let text = rows(20, 1e-3).replacen(",1,0.5,", &format!(",{cell},0.5,"), 3);
    let p = temp_file("long-cell", text.as_bytes());
    let msg = read(&p).unwrap_err().to_string();
    assert!(msg.contains(&format!("`{}…` (100000 bytes)", "x".repeat(80))), "{msg}");
    assert!(msg.len() < 300, "{msg}");
    // A short cell is quoted whole.
    let text = rows(20, 1e-3).replacen(",1,0.5,", ",1.2.3,0.5,", 1);
    let p2 = temp_file("short-cell", text.as_bytes());
    let msg = read(&p2).unwrap_err().to_string();
    assert!(msg.contains("`1.2.3`") && !msg.contains("…"), "{msg}");
    std::fs::remove_file(p).ok();
    std::fs::remove_file(p2).ok();
}

#[test]
fn too_many_fields_and_rows_and_too_long_lines_are_refused() {
    // 5000 header fields: more than the default 4096.
    let header: Vec<String> = (0..5000).map(|k| format!("c{k}")).collect();
    let p = temp_file("fields", format!("t,ud,uq,id,iq,w_m,{}\n", header.join(",")).as_bytes());
    let err = read(&p).unwrap_err();
    assert!(matches!(&err, Error::LimitExceeded { line: 1, limit, .. } if limit == "max_fields"), "{err:?}");
    std::fs::remove_file(p).ok();

    let p = temp_file("rows", rows(20, 1e-3).as_bytes());
    let with = |limits: ReadLimits| {
        read_log(&p, &CsvOptions { pole_pairs: Some(4), limits, ..CsvOptions::default() })
    };
    let err = with(ReadLimits { max_rows: 10, ..ReadLimits::default() }).unwrap_err();
    // Row 10 (0-based) is line 12.
    assert!(
        matches!(&err, Error::LimitExceeded { line: 12, limit, max: 10, .. } if limit == "max_rows"),
        "{err:?}"
    );
    assert!(err.to_string().contains("max_rows"), "{err}");
    assert_eq!(with(ReadLimits { max_rows: 20, ..ReadLimits::default() }).unwrap().len(), 20);
    let err = with(ReadLimits { max_line_bytes: 10, ..ReadLimits::default() }).unwrap_err();
    assert!(matches!(&err, Error::LimitExceeded { line: 1, .. }), "{err:?}");
    let err = with(ReadLimits { max_fields: 5, ..ReadLimits::default() }).unwrap_err();
    assert!(matches!(&err, Error::LimitExceeded { line: 1, max: 5, .. }), "{err:?}");
    // The generic reader takes the same limits.
    let spec = CsvSpec {
        columns: vec![ColumnMap::new("ud", "ud", "V")],
        limits: ReadLimits { max_rows: 5, ..ReadLimits::default() },
        ..CsvSpec::default()
    };
    let err = read_csv(&p, &spec).unwrap_err();
    assert!(matches!(&err, Error::LimitExceeded { line: 7, .. }), "{err:?}");
    // Limits round-trip through serde with their defaults.
    let limits: ReadLimits = serde_json::from_str(r#"{"max_rows": 7}"#).unwrap();
    assert_eq!(limits, ReadLimits { max_rows: 7, ..ReadLimits::default() });
    std::fs::remove_file(p).ok();
}

#[test]
fn rows_are_validated_as_they_stream() {
    // A NaN at row 3 stops the read there, before the ragged row 10 is reached; the error
    // names the configured column.
    let columns = ColumnNames { i_q: "iq_A".into(), ..ColumnNames::default() };
    let mut lines: Vec<String> = rows(20, 1e-3).replace("iq", "iq_A").lines().map(String::from).collect();
    lines[4] = lines[4].replace("-0.25", "nan");
    lines[11].push_str(",extra");
    let p = temp_file("nan-stream", (lines.join("\n") + "\n").as_bytes());
    let err =
        read_log(&p, &CsvOptions { pole_pairs: Some(4), columns, ..CsvOptions::default() }).unwrap_err();
    assert!(matches!(&err, Error::NonFinite { column, row: 3, .. } if column == "iq_A"), "{err:?}");
    std::fs::remove_file(p).ok();
    // A repeated time stamp at row 2, likewise.
    let mut lines: Vec<String> = rows(20, 1e-3).lines().map(String::from).collect();
    lines[3] = lines[2].clone();
    lines[11].push_str(",extra");
    let p = temp_file("step-stream", (lines.join("\n") + "\n").as_bytes());
    let err = read(&p).unwrap_err();
    assert!(matches!(&err, Error::NonUniformTime { row: 2, .. }), "{err:?}");
    std::fs::remove_file(p).ok();
}

#[test]
fn a_wanted_column_named_twice_is_an_error_naming_both_positions() {
    let text = rows(20, 1e-3).replace(HEADER, "t,ud,uq,id,iq,w_m,uq\n").replace(",10\n", ",10,0\n");
    let p = temp_file("dup", text.as_bytes());
    let err = read(&p).unwrap_err();
    assert!(
        matches!(&err, Error::DuplicateColumn { column, first: 3, second: 7, .. } if column == "uq"),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(msg.contains("`uq`") && msg.contains('3') && msg.contains('7'), "{msg}");
    std::fs::remove_file(p).ok();
    // An optional column counts too; unused columns may share a name.
    let text =
        rows(20, 1e-3).replace(HEADER, "t,ud,uq,id,iq,w_m,ud_ref,ud_ref\n").replace(",10\n", ",10,0,0\n");
    let p = temp_file("dup-optional", text.as_bytes());
    assert!(matches!(read(&p).unwrap_err(), Error::DuplicateColumn { first: 7, second: 8, .. }));
    std::fs::remove_file(p).ok();
    let text = rows(20, 1e-3).replace(HEADER, "t,ud,uq,id,iq,w_m,note,note\n").replace(",10\n", ",10,a,b\n");
    let p = temp_file("dup-unused", text.as_bytes());
    assert_eq!(read(&p).unwrap().len(), 20);
    std::fs::remove_file(p).ok();
}

#[test]
fn pole_pairs_outside_1_to_100_are_refused() {
    let p = temp_file("np", rows(20, 1e-3).as_bytes());
    for n_p in [0, 101] {
        let err = read_log(&p, &CsvOptions { pole_pairs: Some(n_p), ..CsvOptions::default() }).unwrap_err();
        assert!(matches!(err.domain(), Some(&PmsmError::InvalidPolePairs { n_p: m }) if m == n_p), "{err:?}");
        assert!(err.to_string().contains("1..=100"), "{err}");
    }
    for n_p in [1, 100] {
        assert!(read_log(&p, &CsvOptions { pole_pairs: Some(n_p), ..CsvOptions::default() }).is_ok());
    }
    std::fs::remove_file(p).ok();
}

#[test]
fn sample_times_outside_100_ns_to_100_ms_need_force() {
    for h in [1.0, 1e-8] {
        let p = temp_file("h", rows(20, h).as_bytes());
        let err = read(&p).unwrap_err();
        assert!(
            matches!(err, Error::ImplausibleSampleTime { h: found, .. } if (found - h).abs() < 1e-6 * h),
            "{err:?}"
        );
        let msg = err.to_string();
        assert!(msg.contains(&*p.to_string_lossy()) && msg.contains("1e-7") && msg.contains("1e-1"), "{msg}");
        assert!(msg.contains("--force"), "{msg}");
        let e =
            read_log(&p, &CsvOptions { pole_pairs: Some(4), force: true, ..CsvOptions::default() }).unwrap();
        assert!((e.h() - h).abs() < 1e-9 * h);
        std::fs::remove_file(p).ok();
    }
    // The bounds themselves are plausible.
    for h in [1e-7, 0.1] {
        let p = temp_file("h-edge", rows(20, h).as_bytes());
        assert!(read(&p).is_ok(), "h = {h}");
        std::fs::remove_file(p).ok();
    }
}

proptest::proptest! {
    /// The row-by-row time check never refuses a column that the whole-column check
    /// (every step within 25 % of the mean step) accepts.
    #[test]
    fn streaming_time_check_accepts_every_uniform_column(
        steps in proptest::collection::vec(0.75f64..1.25, 1..200),
        t0 in -1.0f64..1.0,
        h in 1e-6f64..1e-2,
    ) {
        let mut t = vec![t0];
        for s in &steps {
            t.push(t.last().unwrap() + s * h);
        }
        let mean = (t[t.len() - 1] - t[0]) / steps.len() as f64;
        let uniform = t.windows(2).all(|w| ((w[1] - w[0]) - mean).abs() <= 0.25 * mean);
        let mut check = greybox::data::TimeSteps::new("t");
        let streamed = t.iter().try_for_each(|&x| check.push(x));
        if uniform {
            proptest::prop_assert!(streamed.is_ok(), "{streamed:?}");
        }
    }
}

/// A value far beyond what a drive logs (a corrupt cell: a speed of 1e299 rad/s, which
/// once chose the steady-state model and failed in its instruments naming no row) is
/// refused naming its column, row and line, and `--force`; the limits themselves pass.
#[test]
fn an_implausible_value_is_named_by_column_and_row() {
    let log = |cell: &str, col: usize| {
        let mut lines: Vec<String> = rows(20, 1e-4).lines().map(String::from).collect();
        let mut row: Vec<&str> = lines[8].split(',').collect();
        row[col] = cell;
        lines[8] = row.join(",");
        temp_file(&format!("implausible-{col}-{}", cell.len()), (lines.join("\n") + "\n").as_bytes())
    };
    for (cell, col, column) in [("1e299", 5, "w_m"), ("-2e6", 3, "id"), ("3e7", 1, "ud")] {
        let p = log(cell, col);
        let err = read(&p).unwrap_err();
        assert!(
            matches!(&err, Error::ImplausibleValue { column: c, row: 7, .. } if c == column),
            "{cell}: {err:?}"
        );
        assert!(err.to_string().contains("--force"), "{err}");
        let forced = CsvOptions { pole_pairs: Some(4), force: true, ..CsvOptions::default() };
        assert!(read_log(&p, &forced).is_ok(), "{cell} with force");
        let out = crate::errors::greybox(&["fit", &p.to_string_lossy(), "-p", "4"]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(&format!("`{column}`")) && stderr.contains("line 9 of the file"), "{stderr}");
    }
    for (cell, col) in [("1e6", 5), ("-1e6", 4), ("1e7", 2)] {
        assert!(read(&log(cell, col)).is_ok(), "{cell} is at the limit");
    }
    // A log read from its phase columns names the dq channel with the columns it comes from.
    let mut s = String::from("t,ia,ib,ic,ua,ub,uc,theta_m,w_m\n");
    for k in 0..20 {
        let ia = if k == 7 { "1e12" } else { "1" };
        s.push_str(&format!("{:e},{ia},-0.5,-0.5,10,-5,-5,0,10\n", k as f64 * 1e-4));
    }
    let p = temp_file("implausible-phases", s.as_bytes());
    let phases = CsvOptions { pole_pairs: Some(4), source: DqSource::Phases, ..CsvOptions::default() };
    let err = read_log(&p, &phases).unwrap_err();
    assert!(
        matches!(&err, Error::ImplausibleValue { column, row: 7, .. } if column == "id (from ia, ib, ic)"),
        "{err:?}"
    );
}
