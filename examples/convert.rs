//! Converts a drive log to another format (Parquet, Arrow IPC or CSV, by the output's
//! extension) with the columns a fit reads, and times reading both back.
//!
//! The log is read with the default columns and units (`pmsm::read_log`), so the output
//! holds `t` and the channels of the dq view (`ud, uq, id, iq, w_m` and, when the log has
//! them, `theta_m, ud_ref, uq_ref`), in SI units; any other column of the input is left out.
//! A fit of the output gives the estimates of a fit of the input, bit for bit
//! (`tests/it/columnar.rs` checks this for Parquet).
//!
//! Then both files are read 7 times each, alternating, and the median wall time of each
//! is printed: the input as it is, the output with only the columns the fit reads.
//!
//! Run: `cargo run --release --example convert -- IN.csv.gz OUT.parquet` (the `parquet`
//! feature is on by default).

use greybox::pmsm::{CsvOptions, read_log};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> greybox::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, output] = args.as_slice() else {
        return Err(greybox::Error::InvalidOption {
            option: "arguments".into(),
            reason: format!("give IN OUT (e.g. log.csv.gz log.parquet), got {} arguments", args.len()),
        });
    };
    let (input, output) = (PathBuf::from(input), PathBuf::from(output));
    let options = CsvOptions::default();
    let log = read_log(&input, &options)?;
    greybox::data::write_log(&output, &log, "t")?;
    let back = read_log(&output, &options)?;
    let same = log.channels().iter().all(|c| back.get(&c.name).is_some_and(|b| b.values == c.values));
    println!(
        "{} -> {}: {} samples, {} channels, values identical on reading back: {same}",
        input.display(),
        output.display(),
        log.len(),
        log.channels().len()
    );
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..7 {
        for (k, path) in [&input, &output].into_iter().enumerate() {
            let t0 = Instant::now();
            read_log(path, &options)?;
            times[k].push(t0.elapsed().as_secs_f64());
        }
    }
    for (k, path) in [&input, &output].into_iter().enumerate() {
        times[k].sort_by(f64::total_cmp);
        let bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
        println!(
            "read {}: median {:.1} ms of 7 ({:.1} MB)",
            path.display(),
            1e3 * times[k][3],
            bytes as f64 / 1e6
        );
    }
    Ok(())
}
