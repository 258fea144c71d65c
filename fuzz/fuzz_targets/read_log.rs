//! cargo-fuzz target: raw bytes (plain, or gzip when they start with its magic) through the
//! PMSM log reader with default options. Any panic, hang or unbounded allocation is a bug;
//! errors are the expected outcome for nearly all inputs.
//!
//! Run (nightly): `cargo +nightly fuzz run read_log fuzz/corpus/read_log -- -rss_limit_mb=256 -timeout=5`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("greybox-fuzz-{}.csv", std::process::id()));
    if std::fs::write(&path, data).is_ok() {
        let _ = greybox::pmsm::read_log(&path, &Default::default());
        let phases = greybox::pmsm::CsvOptions {
            pole_pairs: Some(4),
            source: greybox::pmsm::DqSource::Phases,
            ..Default::default()
        };
        let _ = greybox::pmsm::read_log(&path, &phases);
    }
});
