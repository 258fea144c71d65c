//! The table readers' streaming time check and [`TimeCheck::Skip`]: a time column that steps
//! back or jumps is refused by default (`read_table`, `read_table_with(.., Streaming)`) and
//! read as it is, every row, when the caller says it checks the steps itself.

use std::path::Path;

use crate::common::TempFile;

use greybox::Error;
use greybox::data::{Delimiter, ReadLimits, Table};
use greybox::data::{TimeCheck, TimeSteps};
use proptest::prelude::*;

/// A fresh path `greybox-timecheck-…-{name}` in the temp folder, removed on drop.
fn temp_path(name: &str) -> TempFile {
    TempFile::new("timecheck", name)
}

/// A time column that is uniform for 5 rows, then steps back (row 5) and jumps (row 8).
const T: [f64; 10] = [0.0, 0.1, 0.2, 0.3, 0.4, 0.15, 0.25, 0.35, 9.0, 9.1];

fn read(path: &Path, time: TimeCheck) -> greybox::Result<Table> {
    let wanted = [("t", true), ("x", true)];
    greybox::data::read_table_with(path, &wanted, &ReadLimits::default(), Delimiter::COMMA, time)
}

fn check(path: &Path) {
    let wanted = [("t", true), ("x", true)];
    for err in [
        greybox::data::read_table(path, &wanted, &ReadLimits::default(), Delimiter::COMMA).unwrap_err(),
        read(path, TimeCheck::Streaming).unwrap_err(),
    ] {
        assert!(
            matches!(&err, Error::NonUniformTime { column, row: 5, .. } if column == "t"),
            "{}: {err}",
            path.display()
        );
    }
    let table = read(path, TimeCheck::Skip).unwrap();
    assert_eq!(table.columns[0].as_deref(), Some(&T[..]), "{}", path.display());
    let x: Vec<f64> = (0..T.len()).map(|k| k as f64).collect();
    assert_eq!(table.columns[1].as_deref(), Some(&x[..]));
}

#[test]
fn a_bad_time_column_is_refused_by_default_and_read_when_the_caller_checks_it() {
    let body: String = T.iter().enumerate().map(|(k, t)| format!("{t},{k}\n")).collect();
    let path = temp_path("steps.csv");
    std::fs::write(&path, format!("t,x\n{body}")).unwrap();
    check(&path);
    // The `csv` parser's path (a quoted cell) checks the same way.
    let quoted = temp_path("quoted.csv");
    std::fs::write(&quoted, format!("t,\"x\"\n{body}")).unwrap();
    check(&quoted);
    // The check is the reader's only one on the time column: a NaN is refused either way.
    let nan = temp_path("nan.csv");
    std::fs::write(&nan, "t,x\n0,0\nnan,1\n").unwrap();
    for time in [TimeCheck::Streaming, TimeCheck::Skip] {
        let err = read(&nan, time).unwrap_err();
        assert!(matches!(&err, Error::NonFinite { column, row: 1, .. } if column == "t"), "{err}");
    }
}

#[cfg(feature = "parquet")]
#[test]
fn a_columnar_log_skips_the_check_the_same_way() {
    use arrow_array::{ArrayRef, Float64Array, RecordBatch};
    use std::sync::Arc;
    let columns: Vec<(&str, ArrayRef)> = vec![
        ("t", Arc::new(Float64Array::from_iter_values(T))),
        ("x", Arc::new(Float64Array::from_iter_values((0..T.len()).map(|k| k as f64)))),
    ];
    let batch = RecordBatch::try_from_iter(columns).unwrap();
    let path = temp_path("steps.parquet");
    let file = std::fs::File::create(&path).unwrap();
    let mut w = parquet::arrow::ArrowWriter::try_new(file, batch.schema(), None).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
    check(&path);
}

/// Row by row, then [`TimeSteps::finish`]: the reference for [`TimeSteps::push_all`].
fn one_by_one(t: &[f64]) -> (greybox::Result<()>, usize, greybox::Result<f64>) {
    let mut steps = TimeSteps::new("t");
    let pushed = t.iter().try_for_each(|&x| steps.push(x));
    (pushed, steps.rows(), steps.finish(t))
}

/// [`TimeSteps::push_all`], then [`TimeSteps::finish`].
fn all_at_once(t: &[f64]) -> (greybox::Result<()>, usize, greybox::Result<f64>) {
    let mut steps = TimeSteps::new("t");
    let pushed = steps.push_all(t);
    (pushed, steps.rows(), steps.finish(t))
}

proptest! {
    /// Whatever the column (jittered steps up to and beyond the fast path's bound, a step
    /// back, a NaN, an offset start), pushing it at once gives what row by row gives: the
    /// same error with the same row, the same count, the same mean step.
    #[test]
    fn pushing_a_column_at_once_is_pushing_it_row_by_row(
        n in 2usize..400,
        t0 in -1e3f64..1e3,
        h in 1e-5f64..1.0,
        jitter in 0.0f64..0.5,
        seed in any::<u64>(),
        fault in 0usize..4,
        at in 0usize..400,
    ) {
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut t: Vec<f64> = Vec::with_capacity(n);
        for k in 0..n {
            let step = if k == 0 { t0 } else { t[k - 1] + h * (1.0 + 2.0 * jitter * next()) };
            t.push(step);
        }
        let at = at % n;
        match fault {
            1 => t[at] = f64::NAN,
            2 if at > 0 => t[at] = t[at - 1],
            3 => t[at] += 10.0 * h,
            _ => {}
        }
        let (a, b) = (one_by_one(&t), all_at_once(&t));
        prop_assert_eq!(format!("{:?}", a.0), format!("{:?}", b.0));
        prop_assert_eq!(a.1, b.1);
        prop_assert_eq!(format!("{:?}", a.2), format!("{:?}", b.2));
    }
}

/// Columns at the ends of the range: a mean step that overflows, and subnormal steps whose
/// relative bound no longer rounds as a relative one, are checked row by row.
#[test]
fn extreme_columns_are_pushed_as_row_by_row() {
    let u = 5e-324;
    for t in [
        vec![-1.7e308, 0.0, 0.5e308],
        vec![0.0, 2.0 * u, 5.0 * u, 9.0 * u],
        vec![1e300, 1e300 + 1e284, 1e300 + 2e284],
    ] {
        let (a, b) = (one_by_one(&t), all_at_once(&t));
        assert_eq!(format!("{:?}", a.0), format!("{:?}", b.0), "{t:?}");
        assert_eq!(a.1, b.1, "{t:?}");
        assert_eq!(format!("{:?}", a.2), format!("{:?}", b.2), "{t:?}");
    }
}

#[test]
fn a_checker_with_rows_pushes_the_rest_row_by_row() {
    let mut steps = TimeSteps::new("t");
    steps.push(0.0).unwrap();
    steps.push(0.1).unwrap();
    // Uniform on its own, but its first step from the rows before is a jump.
    let err = steps.push_all(&[5.0, 5.1, 5.2]).unwrap_err();
    assert!(matches!(err, Error::NonUniformTime { row: 2, .. }), "{err}");
    let mut steps = TimeSteps::new("t");
    steps.push_all(&[0.0, 0.1]).unwrap();
    steps.push_all(&[0.2, 0.3]).unwrap();
    assert_eq!(steps.rows(), 4);
}
