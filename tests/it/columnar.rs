//! Columnar logs (feature `parquet`): the same log as CSV, gzip CSV, Parquet and Arrow IPC
//! reads into bit-identical experiments and fits to bit-identical estimates; the columnar
//! reader's errors name the culprit (missing, duplicate or non-numeric column, null,
//! NaN, non-monotone time); numeric types of any width read as f64.
//!
//! Without the feature (`cargo test --no-default-features --lib` builds the library alone;
//! the integration tests need the `cli` feature's binary) a columnar path gives
//! `Error::Format` naming the feature: `without_the_feature_columnar_files_name_it` below,
//! compiled only then.

use crate::common::TempFile;

use greybox::Error;
use greybox::data::Experiment;
use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{CsvOptions, read_log};

/// The path `name` in a fresh folder `greybox-columnar-…` (the file's stem is the log's
/// name; a simulated log's truth is written beside it), removed with it on drop.
fn temp_path(name: &str) -> TempFile {
    TempFile::in_dir("columnar", name)
}

/// A short exp3 log from the drive simulator: `n` samples at 10 kHz.
fn log(n: usize) -> Experiment {
    let cfg = DriveConfig { duration: (n - 1) as f64 * 1e-4, ..scenario("exp3", SPM_MOTOR).unwrap() };
    simulate_drive(&cfg).unwrap().experiment
}

#[allow(dead_code)] // only with the feature
fn bits(e: &Experiment) -> Vec<(String, Vec<u64>)> {
    let mut out = vec![("h".to_string(), vec![e.h().to_bits()])];
    out.extend(e.channels().iter().map(|c| (c.name.clone(), c.values.iter().map(|x| x.to_bits()).collect())));
    out
}

fn options() -> CsvOptions {
    CsvOptions { pole_pairs: Some(SPM_MOTOR.n_p), ..CsvOptions::default() }
}

#[cfg(feature = "parquet")]
mod with_feature {
    use super::*;
    use arrow_array::{
        ArrayRef, Float32Array, Float64Array, Int16Array, RecordBatch, StringArray, UInt64Array,
    };
    use greybox::data::write_log;
    use greybox::pmsm::{PmsmFitOptions, fit_pmsm};
    use std::sync::Arc;

    #[test]
    fn csv_parquet_and_arrow_read_bit_identically_and_fit_identically() {
        let e = log(4_000);
        let names = ["log.csv", "log.csv.gz", "log.parquet", "log.arrow", "log.feather"];
        let read: Vec<Experiment> = names
            .iter()
            .map(|name| {
                let path = temp_path(name);
                write_log(&path, &e, "t").unwrap();
                let r = read_log(&path, &options()).unwrap();
                std::fs::remove_file(&path).ok();
                r
            })
            .collect();
        for (name, r) in names.iter().zip(&read) {
            assert_eq!(r.name(), "log", "{name}");
            assert_eq!(bits(r), bits(&read[0]), "{name}");
        }
        let fit = |e: &Experiment| {
            let f = fit_pmsm(std::slice::from_ref(e), &PmsmFitOptions::new(SPM_MOTOR.n_p)).unwrap();
            serde_json::to_string(&f.report.parameters).unwrap()
        };
        assert_eq!(fit(&read[0]), fit(&read[2]));
        assert_eq!(fit(&read[0]), fit(&read[3]));
    }

    /// A table in memory (`LogSource::Arrow`, what the Python package hands over) reads as
    /// its Parquet file does, bit for bit, split into batches or not; its errors name the
    /// table and the row.
    #[test]
    fn record_batches_in_memory_read_as_the_file() {
        use greybox::data::to_record_batch;
        use greybox::pmsm::{LogSource, read_log_from};
        let e = log(4_000);
        let path = temp_path("log.parquet");
        write_log(&path, &e, "t").unwrap();
        let from_file = read_log(&path, &options()).unwrap();
        std::fs::remove_file(&path).ok();
        let batch = to_record_batch(&e, "t").unwrap();
        let schema = batch.schema();
        let pieces: Vec<RecordBatch> = (0..4).map(|k| batch.slice(k * 1_000, 1_000)).collect();
        for batches in [vec![batch.clone()], pieces] {
            let source = LogSource::Arrow { name: "log", schema: &schema, batches: &batches };
            assert_eq!(bits(&read_log_from(source, &options()).unwrap()), bits(&from_file));
        }
        let mut iq: Vec<f64> = e.channel("iq").unwrap().to_vec();
        iq[17] = f64::NAN;
        let columns: Vec<(String, ArrayRef)> = schema
            .fields()
            .iter()
            .zip(batch.columns())
            .map(|(f, c)| {
                let c = if f.name() == "iq" {
                    Arc::new(Float64Array::from(iq.clone())) as ArrayRef
                } else {
                    c.clone()
                };
                (f.name().clone(), c)
            })
            .collect();
        let bad = RecordBatch::try_from_iter(columns).unwrap();
        let source =
            LogSource::Arrow { name: "table", schema: &bad.schema(), batches: std::slice::from_ref(&bad) };
        let err = read_log_from(source, &options()).unwrap_err();
        assert!(matches!(&err, Error::NonFinite { column, row: 17, .. } if column == "iq"), "{err}");
    }

    /// A table read by a column spec (`LogSource::read_spec`, what the mechanics of a given
    /// K_t read) is its file's experiment bit for bit; and the reports that read logs
    /// (`app::mechanics` here) give the same JSON from the table as from its file.
    #[test]
    fn a_table_read_by_a_spec_and_reported_is_its_file() {
        use greybox::app::{MechanicsRequest, mechanics};
        use greybox::data::{ColumnMap, CsvSpec, to_record_batch};
        use greybox::pmsm::LogSource;
        let e = log(4_000);
        let path = temp_path("spec.parquet");
        write_log(&path, &e, "t").unwrap();
        let batch = to_record_batch(&e, "t").unwrap();
        let schema = batch.schema();
        let batches = [batch];
        let table = LogSource::Arrow { name: "spec", schema: &schema, batches: &batches };
        let spec = CsvSpec {
            columns: vec![
                ColumnMap::new("iq", "iq", "A"),
                ColumnMap { scale: 2.0, ..ColumnMap::new("w_m", "w", "rad/s") },
            ],
            ..Default::default()
        };
        let file = LogSource::Path(&path);
        assert_eq!(bits(&table.read_spec(&spec).unwrap()), bits(&file.read_spec(&spec).unwrap()));
        let request = MechanicsRequest { k_t: Some(0.66), ..MechanicsRequest::new(SPM_MOTOR.n_p) };
        // Every fit's wall-clock `timing` removed, wherever it is nested.
        fn untimed(v: serde_json::Value) -> serde_json::Value {
            match v {
                serde_json::Value::Object(m) => {
                    m.into_iter().filter(|(k, _)| k != "timing").map(|(k, v)| (k, untimed(v))).collect()
                }
                serde_json::Value::Array(a) => a.into_iter().map(untimed).collect(),
                v => v,
            }
        }
        let without_timing = |json: &str| untimed(serde_json::from_str(json).unwrap());
        let from_table = mechanics(&[table], &request).unwrap();
        let from_file = mechanics(&[file], &request).unwrap();
        std::fs::remove_file(&path).ok();
        assert_eq!(without_timing(&from_table.json), without_timing(&from_file.json));
        assert_eq!(from_table.untrusted, from_file.untrusted);
    }

    /// A flux map handed over as a table reads as its Parquet file: the same points to the
    /// bit, the same torque, the table's name.
    #[test]
    fn a_flux_map_table_reads_as_its_file() {
        use greybox::pmsm::{FluxMapColumns, LogSource, read_flux_map_from, read_flux_map_with};
        let n = 30;
        let k = || (0..n).map(|k| k as f64);
        let columns = vec![
            ("i_d", f64s(k().map(|k| -10.0 + 0.3 * k))),
            ("i_q", f64s(k().map(|k| (0.7 * k).sin() * 12.0))),
            ("psi_d", f64s(k().map(|k| 0.1 + 0.002 * k))),
            ("psi_q", f64s(k().map(|k| 0.03 * (0.7 * k).sin()))),
            ("torque", f64s(k().map(|k| 0.5 * k))),
        ];
        let batch = RecordBatch::try_from_iter(columns.clone()).unwrap();
        let [pq, _ipc] = columnar("fluxmap", columns);
        let c = FluxMapColumns::default();
        let file = read_flux_map_with(pq.path(), &c).unwrap();
        let batches = [batch];
        let table = read_flux_map_from(
            LogSource::Arrow { name: "map", schema: &batches[0].schema(), batches: &batches },
            &c,
        )
        .unwrap();
        assert_eq!(table.map.name(), "map");
        assert_eq!(bits(&table.map), bits(&file.map));
        assert_eq!(table.torque, file.torque);
        assert!(table.torque.is_some());
    }

    /// Writes `columns` (name, array) as Parquet and as Arrow IPC; both paths.
    fn columnar(tag: &str, columns: Vec<(&str, ArrayRef)>) -> [TempFile; 2] {
        let batch = RecordBatch::try_from_iter(columns).unwrap();
        let pq = temp_path(&format!("{tag}.parquet"));
        let mut w =
            parquet::arrow::ArrowWriter::try_new(std::fs::File::create(&pq).unwrap(), batch.schema(), None)
                .unwrap();
        w.write(&batch).unwrap();
        w.close().unwrap();
        let ipc = temp_path(&format!("{tag}.arrow"));
        let mut w =
            arrow_ipc::writer::FileWriter::try_new(std::fs::File::create(&ipc).unwrap(), &batch.schema())
                .unwrap();
        w.write(&batch).unwrap();
        w.finish().unwrap();
        [pq, ipc]
    }

    fn f64s(v: impl IntoIterator<Item = f64>) -> ArrayRef {
        Arc::new(Float64Array::from_iter_values(v))
    }

    const N: usize = 40;

    /// The columns of a valid log, `t` in µs steps of 100 (10 kHz).
    fn valid() -> Vec<(&'static str, ArrayRef)> {
        let t = (0..N).map(|k| k as f64 * 1e-4);
        vec![
            ("t", f64s(t)),
            ("ud", f64s((0..N).map(|k| (k as f64).sin()))),
            ("uq", Arc::new(Float32Array::from_iter_values((0..N).map(|k| k as f32 * 0.5))) as ArrayRef),
            ("id", Arc::new(Int16Array::from_iter_values((0..N).map(|k| k as i16 - 7))) as ArrayRef),
            ("iq", Arc::new(UInt64Array::from_iter_values((0..N).map(|k| k as u64 * 3))) as ArrayRef),
            ("w_m", f64s((0..N).map(|_| 10.0))),
            ("note", Arc::new(StringArray::from_iter_values((0..N).map(|k| format!("row {k}")))) as ArrayRef),
        ]
    }

    #[test]
    fn numeric_columns_of_any_type_read_as_f64() {
        for path in columnar("types", valid()) {
            let e = read_log(&path, &options()).unwrap();
            assert_eq!(e.len(), N);
            assert_eq!(e.channel("uq").unwrap()[3], 1.5);
            assert_eq!(e.channel("id").unwrap()[0], -7.0);
            assert_eq!(e.channel("iq").unwrap()[2], 6.0);
            assert!((e.h() - 1e-4).abs() < 1e-15);
        }
    }

    fn with(name: &str, array: ArrayRef) -> Vec<(&'static str, ArrayRef)> {
        valid().into_iter().map(|(n, a)| if n == name { (n, array.clone()) } else { (n, a) }).collect()
    }

    #[test]
    fn errors_name_the_culprit() {
        for path in columnar("missing", valid().into_iter().filter(|(n, _)| *n != "iq").collect()) {
            let err = read_log(&path, &options()).unwrap_err();
            assert!(matches!(&err, Error::MissingColumn { column, .. } if column == "iq"), "{err:?}");
        }
        let text: ArrayRef = Arc::new(StringArray::from_iter_values((0..N).map(|k| k.to_string())));
        for path in columnar("string", with("uq", text)) {
            let err = read_log(&path, &options()).unwrap_err();
            assert!(matches!(&err, Error::ColumnType { column, .. } if column == "uq"), "{err:?}");
            assert!(err.to_string().contains("`uq`") && err.to_string().contains("Utf8"), "{err}");
        }
        let t = f64s((0..N).map(|k| if k == 9 { 0.0 } else { k as f64 * 1e-4 }));
        for path in columnar("time", with("t", t)) {
            let err = read_log(&path, &options()).unwrap_err();
            assert!(matches!(&err, Error::NonUniformTime { column, row: 9, .. } if column == "t"), "{err:?}");
        }
        // A NaN at row 5 comes before the bad time step at row 9; the error names the column.
        let t = f64s((0..N).map(|k| if k == 9 { 0.0 } else { k as f64 * 1e-4 }));
        let nan = f64s((0..N).map(|k| if k == 5 { f64::NAN } else { 1.0 }));
        let mut cols = with("t", t);
        cols[5].1 = nan;
        for path in columnar("nan", cols) {
            let err = read_log(&path, &options()).unwrap_err();
            assert!(matches!(&err, Error::NonFinite { column, row: 5, .. } if column == "w_m"), "{err:?}");
        }
        let null: ArrayRef = Arc::new(Float64Array::from_iter((0..N).map(|k| (k != 4).then_some(1.0))));
        for path in columnar("null", with("ud", null)) {
            let err = read_log(&path, &options()).unwrap_err();
            assert!(matches!(&err, Error::Format { .. }), "{err:?}");
            assert!(err.to_string().contains("`ud`") && err.to_string().contains("row 4"), "{err}");
        }
        let mut dup = valid();
        dup[6].0 = "uq";
        for path in columnar("dup", dup) {
            let err = read_log(&path, &options()).unwrap_err();
            assert!(
                matches!(&err, Error::DuplicateColumn { column, first: 3, second: 7, .. } if column == "uq"),
                "{err:?}"
            );
        }
        // Not a Parquet file at all.
        let path = temp_path("junk.parquet");
        std::fs::write(&path, b"t,ud\n0,1\n").unwrap();
        assert!(matches!(read_log(&path, &options()).unwrap_err(), Error::Format { .. }));
        // Rows beyond the limit.
        let limits = greybox::data::ReadLimits { max_rows: 10, ..Default::default() };
        for path in columnar("rows", valid()) {
            let err = read_log(&path, &CsvOptions { limits, ..options() }).unwrap_err();
            assert!(
                matches!(&err, Error::LimitExceeded { limit, max: 10, .. } if limit == "max_rows"),
                "{err:?}"
            );
        }
    }

    #[cfg(feature = "cli")]
    /// Columnar bombs: 4 million rows of zeros, compressed to kilobytes. What decoding would
    /// take is known from the metadata alone (IPC batch headers; Parquet row groups' rows and
    /// uncompressed page sizes): 183 MB from a file more than 50 times smaller is refused
    /// before anything is decoded, whether in one IPC batch or many, one Parquet page or
    /// many (a page is decompressed whole, so reading row 1 of a one-page column would
    /// decode it all). Peak memory and time are in the issue note.
    #[test]
    fn columnar_bombs_are_refused_before_they_are_decoded() {
        use arrow_ipc::writer::IpcWriteOptions;
        let n = 4_000_000;
        let zero: ArrayRef = Arc::new(Float64Array::from(vec![0.0; n]));
        let names = ["t", "ud", "uq", "id", "iq", "w_m"];
        let batch = RecordBatch::try_from_iter(names.iter().map(|n| (*n, zero.clone()))).unwrap();
        let zstd = || {
            IpcWriteOptions::default().try_with_compression(Some(arrow_ipc::CompressionType::ZSTD)).unwrap()
        };
        let ipc = temp_path("bomb.arrow");
        let f = std::fs::File::create(&ipc).unwrap();
        let mut w = arrow_ipc::writer::FileWriter::try_new_with_options(f, &batch.schema(), zstd()).unwrap();
        w.write(&batch).unwrap();
        w.finish().unwrap();
        let stream = temp_path("bomb.arrows");
        let f = std::fs::File::create(&stream).unwrap();
        let mut w =
            arrow_ipc::writer::StreamWriter::try_new_with_options(f, &batch.schema(), zstd()).unwrap();
        for k in (0..n).step_by(1 << 16) {
            w.write(&batch.slice(k, (1 << 16).min(n - k))).unwrap();
        }
        w.finish().unwrap();
        let pq = temp_path("bomb.parquet");
        let props = parquet::file::properties::WriterProperties::builder()
            .set_compression(parquet::basic::Compression::ZSTD(Default::default()))
            .set_max_row_group_row_count(Some(n))
            .build();
        let f = std::fs::File::create(&pq).unwrap();
        let mut w = parquet::arrow::ArrowWriter::try_new(f, batch.schema(), Some(props)).unwrap();
        w.write(&batch).unwrap();
        w.close().unwrap();
        let page = temp_path("bomb-page.parquet");
        let props = parquet::file::properties::WriterProperties::builder()
            .set_compression(parquet::basic::Compression::ZSTD(Default::default()))
            .set_max_row_group_row_count(Some(n))
            .set_dictionary_enabled(false)
            .set_data_page_size_limit(usize::MAX)
            .set_data_page_row_count_limit(usize::MAX)
            .set_write_batch_size(n)
            .build();
        let f = std::fs::File::create(&page).unwrap();
        let mut w = parquet::arrow::ArrowWriter::try_new(f, batch.schema(), Some(props)).unwrap();
        w.write(&batch).unwrap();
        w.close().unwrap();
        for path in [&ipc, &stream, &pq, &page] {
            let says = "decompression bomb";
            let size = std::fs::metadata(path).unwrap().len();
            let err = read_log(path, &options()).unwrap_err().to_string();
            eprintln!("{} ({size} bytes): {err}", path.display());
            assert!(size < 2 << 20 && err.contains(says), "{err}");
            std::fs::remove_file(path).ok();
        }
    }

    #[test]
    fn simulate_writes_parquet_that_fit_reads() {
        let path = temp_path("sim.parquet");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_greybox"))
            .args(["simulate", "--scenario", "exp3", "--duration", "0.2", "-o"])
            .arg(&path)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(path.with_file_name("sim.truth.json").is_file());
        let e = read_log(&path, &options()).unwrap();
        assert_eq!(e.len(), 2001);
    }
}

#[cfg(not(feature = "parquet"))]
#[test]
fn without_the_feature_columnar_files_name_it() {
    let path = temp_path("log.parquet");
    let err = greybox::data::write_log(&path, &log(100), "t").unwrap_err();
    assert!(matches!(err, Error::Format { .. }) && err.to_string().contains("`parquet`"), "{err}");
    std::fs::write(&path, b"PAR1").unwrap();
    let err = read_log(&path, &options()).unwrap_err();
    assert!(matches!(err, Error::Format { .. }) && err.to_string().contains("`parquet`"), "{err}");
}
