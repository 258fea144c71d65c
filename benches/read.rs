//! Criterion benches of the log readers on a 512 000-row exp3 log from the drive simulator
//! (12 columns, written to a temporary folder): CSV gzip and plain, and with the feature
//! `parquet` Parquet and Arrow IPC, each through `read_log` with the default options.
//!
//! Run: `cargo bench --bench read`.

use criterion::{Criterion, criterion_group};
use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::read_log;
use std::hint::black_box;

fn benches(c: &mut Criterion) {
    let n = 512_000;
    let cfg = DriveConfig { duration: (n - 1) as f64 * 1e-4, ..scenario("exp3", SPM_MOTOR).unwrap() };
    let log = simulate_drive(&cfg).unwrap().experiment;
    let dir = std::env::temp_dir().join(format!("greybox-bench-read-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut g = c.benchmark_group("read");
    g.sample_size(10);
    let names: &[&str] = if cfg!(feature = "parquet") {
        &["log.csv.gz", "log.csv", "log.parquet", "log.arrow"]
    } else {
        &["log.csv.gz", "log.csv"]
    };
    for name in names {
        let path = dir.join(name);
        greybox::data::write_log(&path, &log, "t").unwrap();
        g.bench_function(format!("512000 rows, {name}"), |b| {
            b.iter(|| black_box(read_log(&path, &Default::default()).unwrap()))
        });
    }
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(read, benches);

fn main() {
    read();
    Criterion::default().configure_from_args().final_summary();
}
