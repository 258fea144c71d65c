//! Parquet and Arrow IPC through the Arrow crates: only the wanted columns decoded, any
//! numeric type converted to f64, Parquet row groups read in parallel.

use std::fs::File;
use std::path::Path;
use std::sync::Arc;

use arrow_array::cast::AsArray;
use arrow_array::types::{
    Float16Type, Float32Type, Float64Type, Int8Type, Int16Type, Int32Type, Int64Type, UInt8Type, UInt16Type,
    UInt32Type, UInt64Type,
};
use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch, RecordBatchReader};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use parquet::arrow::ProjectionMask;
use parquet::arrow::arrow_reader::{
    ArrowReaderMetadata, ArrowReaderOptions, ParquetRecordBatchReaderBuilder,
};
use rayon::prelude::*;

use super::budget::check_budget;
use super::check;
use crate::data::experiment::Experiment;
use crate::data::table::{ReadLimits, Table, experiment_name, find_columns};
use crate::data::time::{TimeCheck, TimeSteps};
use crate::data::write_atomic;
use crate::error::{Error, Result};

/// Rows per Parquet row group written: eight groups for 512 000 rows, read in parallel.
const ROW_GROUP: usize = 1 << 16;

/// Rows per decoded batch: 64 KiB a column, reused from the heap rather than mapped anew.
const BATCH: usize = 1 << 13;

/// The file at `path`, opened for reading.
///
/// # Errors
/// [`Error::Io`] naming the path.
fn open(path: &Path) -> Result<File> {
    File::open(path).map_err(|source| Error::Io { path: path.to_path_buf(), source })
}

fn format_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Format { path: path.to_path_buf(), message: e.to_string() }
}

/// Reads the `wanted` columns of a Parquet file (`parquet`) or an Arrow IPC one: the
/// columnar half of [`crate::data::read_table_with`], whose errors it returns.
pub(crate) fn read(
    path: &Path,
    parquet: bool,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    time: TimeCheck,
) -> Result<Table> {
    let file = open(path)?;
    let streaming = time == TimeCheck::Streaming;
    let (header, index, columns, rows) = if parquet {
        read_parquet(path, file, wanted, limits, streaming)?
    } else {
        read_ipc(path, file, wanted, limits, streaming)?
    };
    // Each wanted column as read, moved rather than copied.
    let values: Vec<Option<Vec<f64>>> = index.iter().zip(columns).map(|(i, c)| i.map(|_| c)).collect();
    check_rows(path, rows, limits)?;
    let time = (time == TimeCheck::Streaming).then(|| wanted.first().map_or("", |w| w.0));
    check::rows(path, time, &header, &index, &values)?;
    Ok(Table { name: experiment_name(path), header, columns: values })
}

/// The header, the wanted columns' positions in it, one vector per wanted column, and the
/// row count.
type Read = (Vec<String>, Vec<Option<usize>>, Vec<Vec<f64>>, u64);

/// The schema's names and the wanted columns' positions in it.
/// [`Error::LimitExceeded`] when a table of `rows` rows holds more than `limits.max_rows`.
pub(super) fn check_rows(path: &Path, rows: u64, limits: &ReadLimits) -> Result<()> {
    if rows <= limits.max_rows {
        return Ok(());
    }
    Err(Error::LimitExceeded {
        path: path.to_path_buf(),
        // The line of the first row too many, were the log a CSV file with a header.
        line: limits.max_rows.saturating_add(2),
        what: format!("more than {} data rows", limits.max_rows),
        limit: "max_rows".into(),
        max: limits.max_rows,
    })
}

pub(super) fn header(
    path: &Path,
    schema: &Schema,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
) -> Result<(Vec<String>, Vec<Option<usize>>)> {
    let header: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
    let index = find_columns(path, &header, wanted, limits)?;
    Ok((header, index))
}

fn read_parquet(
    path: &Path,
    file: File,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    streaming: bool,
) -> Result<Read> {
    let meta =
        ArrowReaderMetadata::load(&file, ArrowReaderOptions::new()).map_err(|e| format_err(path, e))?;
    let (header, index) = header(path, meta.schema(), wanted, limits)?;
    let rows = u64::try_from(meta.metadata().file_metadata().num_rows()).unwrap_or(0);
    if rows > limits.max_rows {
        return Ok((header, index.iter().map(|_| None).collect(), vec![Vec::new(); wanted.len()], rows));
    }
    let picked: Vec<usize> = index.iter().flatten().copied().collect();
    // What decoding would take, from the metadata alone: per row group and wanted column the
    // larger of its f64 values and its uncompressed pages (a page is decompressed whole).
    let schema = meta.parquet_schema();
    let decoded: u64 = meta
        .metadata()
        .row_groups()
        .iter()
        .map(|g| {
            let rows = u64::try_from(g.num_rows()).unwrap_or(u64::MAX);
            (0..g.num_columns())
                .filter(|&c| picked.contains(&schema.get_column_root_idx(c)))
                .map(|c| {
                    rows.saturating_mul(8)
                        .max(u64::try_from(g.column(c).uncompressed_size()).unwrap_or(u64::MAX))
                })
                .fold(0u64, u64::saturating_add)
        })
        .fold(0u64, u64::saturating_add);
    check_budget(path, file.metadata().map(|m| m.len()).unwrap_or(0), rows, decoded)?;
    // The time column streamed first, a batch at a time, before anything the size of the
    // declared record is allocated: a bad step ends the read there, and the rows up to it
    // (every wanted column) give the first error in row order, as the CSV reader would.
    if let (true, Some(Some(t))) = (streaming, index.first()) {
        let reader = |columns: &[usize], limit: usize| {
            ParquetRecordBatchReaderBuilder::new_with_metadata(open(path)?, meta.clone())
                .with_projection(ProjectionMask::roots(meta.parquet_schema(), columns.iter().copied()))
                .with_batch_size(BATCH)
                .with_limit(limit)
                .build()
                .map_err(|e| format_err(path, e))
        };
        let mut steps = TimeSteps::new(header[*t].clone());
        let (mut at, mut failed) = (0, None);
        for batch in reader(&[*t], usize::MAX)? {
            let batch = batch.map_err(|e| format_err(path, e))?;
            let mut values = Vec::with_capacity(batch.num_rows());
            append(path, &header[*t], batch.column(0), at, &mut values)?;
            if let Some(bad) = values.iter().position(|v| steps.push(*v).is_err()) {
                failed = Some(at + bad);
                break;
            }
            at += batch.num_rows();
        }
        if let Some(row) = failed {
            let head = collect(path, reader(&picked, row + 1)?, &header, &index, false)?;
            return Ok((header, index, head, (row + 1) as u64));
        }
    }
    let groups = meta.metadata().num_row_groups();
    let sizes: Vec<usize> =
        meta.metadata().row_groups().iter().map(|g| usize::try_from(g.num_rows()).unwrap_or(0)).collect();
    let total: usize = sizes.iter().sum();
    // Each wanted column allocated once, each row group decoded into its own rows of it.
    let mut columns: Vec<Vec<f64>> =
        index.iter().map(|i| if i.is_some() { vec![0.0; total] } else { Vec::new() }).collect();
    let mut slices: Vec<Vec<Option<&mut [f64]>>> = (0..groups).map(|_| Vec::new()).collect();
    for (c, i) in columns.iter_mut().zip(&index) {
        let mut rest = c.as_mut_slice();
        for (g, &n) in sizes.iter().enumerate() {
            if i.is_some() {
                let (head, tail) = std::mem::take(&mut rest).split_at_mut(n);
                slices[g].push(Some(head));
                rest = tail;
            } else {
                slices[g].push(None);
            }
        }
    }
    // One reader per row group, each on its own file handle (a cloned handle would share
    // the file offset between threads).
    slices.into_par_iter().enumerate().try_for_each(|(g, mut out)| {
        let file = open(path)?;
        let mask = ProjectionMask::roots(meta.parquet_schema(), picked.iter().copied());
        let reader = ParquetRecordBatchReaderBuilder::new_with_metadata(file, meta.clone())
            .with_projection(mask)
            .with_batch_size(BATCH)
            .with_row_groups(vec![g])
            .build()
            .map_err(|e| format_err(path, e))?;
        let mut at = 0;
        for batch in reader {
            let batch = batch.map_err(|e| format_err(path, e))?;
            let end = at + batch.num_rows();
            for (slot, i) in out.iter_mut().zip(&index) {
                let (Some(slot), Some(i)) = (slot, i) else { continue };
                let array = column(path, &batch, &header[*i])?;
                let Some(dst) = slot.get_mut(at..end).filter(|d| d.len() == array.len()) else {
                    return Err(format_err(
                        path,
                        format!("row group {g} holds more rows than its metadata says"),
                    ));
                };
                convert(path, &header[*i], array, at, dst)?;
            }
            at = end;
        }
        Ok(())
    })?;
    Ok((header, index, columns, rows))
}

fn column<'b>(path: &Path, batch: &'b RecordBatch, name: &str) -> Result<&'b ArrayRef> {
    batch
        .column_by_name(name)
        .ok_or_else(|| format_err(path, format!("column `{name}` missing from a batch")))
}

fn read_ipc(
    path: &Path,
    file: File,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    streaming: bool,
) -> Result<Read> {
    use arrow_ipc::reader::{FileReader, StreamReader};
    // An IPC file (Feather v2) has a footer to seek; a stream (`.arrows`) has none.
    let reader = |file: File, projection: Option<Vec<usize>>| -> Result<Box<dyn RecordBatchReader>> {
        Ok(match FileReader::try_new_buffered(file, projection.clone()) {
            Ok(r) => Box::new(r),
            Err(file_err) => match StreamReader::try_new_buffered(open(path)?, projection) {
                Ok(r) => Box::new(r),
                Err(_) => return Err(format_err(path, file_err)),
            },
        })
    };
    let size = file.metadata().map(|m| m.len()).unwrap_or(0);
    let (header, index) = header(path, &reader(file, None)?.schema(), wanted, limits)?;
    // What the batches declare, before any is decoded.
    let total = super::ipc_scan::declared_rows(path)?;
    if total > limits.max_rows {
        return Ok((header, index.iter().map(|_| None).collect(), vec![Vec::new(); wanted.len()], total));
    }
    let picked: Vec<usize> = index.iter().flatten().copied().collect();
    check_budget(path, size, total, total.saturating_mul(8 * picked.len() as u64))?;
    let mut sorted = picked.clone();
    sorted.sort_unstable();
    let projected = reader(open(path)?, Some(sorted))?;
    let values = collect(path, projected, &header, &index, streaming)?;
    let rows = values.iter().map(Vec::len).max().unwrap_or(0) as u64;
    // Grown batch by batch: the slack goes before the columns outlive the read.
    let values = values
        .into_iter()
        .map(|mut v| {
            v.shrink_to_fit();
            v
        })
        .collect();
    Ok((header, index, values, rows))
}

/// The wanted columns of every batch, as f64, one vector per wanted column.
/// With `streaming`, the time column (the first wanted) is checked batch by batch and the
/// read stops after the batch of its first bad step (the caller's row checks then find it).
pub(super) fn collect(
    path: &Path,
    reader: impl Iterator<Item = std::result::Result<RecordBatch, arrow_schema::ArrowError>>,
    header: &[String],
    index: &[Option<usize>],
    streaming: bool,
) -> Result<Vec<Vec<f64>>> {
    let mut out: Vec<Vec<f64>> = vec![Vec::new(); index.len()];
    let mut row = 0;
    let mut steps = index.first().copied().flatten().map(|t| TimeSteps::new(header[t].clone()));
    for batch in reader {
        let batch = batch.map_err(|e| format_err(path, e))?;
        for (v, i) in out.iter_mut().zip(index) {
            let Some(i) = *i else { continue };
            let name = &header[i];
            let column = batch
                .column_by_name(name)
                .ok_or_else(|| format_err(path, format!("column `{name}` missing from a batch")))?;
            append(path, name, column, row, v)?;
        }
        let first = row;
        row += batch.num_rows();
        if let (true, Some(steps), Some(t)) = (streaming, steps.as_mut(), out.first())
            && t.get(first..).is_some_and(|new| new.iter().any(|v| steps.push(*v).is_err()))
        {
            break;
        }
    }
    Ok(out)
}

/// Appends `array` converted to f64; `row` is its first row in the file.
fn append(path: &Path, name: &str, array: &ArrayRef, row: usize, out: &mut Vec<f64>) -> Result<()> {
    let start = out.len();
    out.resize(start + array.len(), 0.0);
    convert(path, name, array, row, &mut out[start..])
}

/// Writes `array` converted to f64 into `out` (of the array's length); `row` is its first
/// row in the file.
fn convert(path: &Path, name: &str, array: &ArrayRef, row: usize, out: &mut [f64]) -> Result<()> {
    if array.null_count() > 0 {
        let at = (0..array.len()).find(|&k| array.is_null(k)).unwrap_or(0) + row;
        return Err(format_err(path, format!("column `{name}` has no value (null) at row {at}")));
    }
    macro_rules! ext {
        ($t:ty, $f:expr) => {
            out.iter_mut().zip(array.as_primitive::<$t>().values().iter().map($f)).for_each(|(o, v)| *o = v)
        };
    }
    match array.data_type() {
        DataType::Float64 => out.copy_from_slice(array.as_primitive::<Float64Type>().values()),
        DataType::Float32 => ext!(Float32Type, |&x| f64::from(x)),
        DataType::Float16 => ext!(Float16Type, |x| x.to_f64()),
        DataType::Int8 => ext!(Int8Type, |&x| f64::from(x)),
        DataType::Int16 => ext!(Int16Type, |&x| f64::from(x)),
        DataType::Int32 => ext!(Int32Type, |&x| f64::from(x)),
        DataType::Int64 => ext!(Int64Type, |&x| x as f64),
        DataType::UInt8 => ext!(UInt8Type, |&x| f64::from(x)),
        DataType::UInt16 => ext!(UInt16Type, |&x| f64::from(x)),
        DataType::UInt32 => ext!(UInt32Type, |&x| f64::from(x)),
        DataType::UInt64 => ext!(UInt64Type, |&x| x as f64),
        other => {
            return Err(Error::ColumnType {
                path: path.to_path_buf(),
                column: name.into(),
                found: other.to_string(),
            });
        }
    }
    Ok(())
}

/// The experiment as one batch: `time` then the channels, f64, units in field metadata.
pub(crate) fn batch(
    e: &Experiment,
    time: &str,
) -> std::result::Result<RecordBatch, arrow_schema::ArrowError> {
    let unit = |u: &str| std::collections::HashMap::from([("unit".to_string(), u.to_string())]);
    let mut fields = vec![Field::new(time, DataType::Float64, false).with_metadata(unit("s"))];
    let mut columns: Vec<ArrayRef> =
        vec![Arc::new(Float64Array::from_iter_values((0..e.len()).map(|k| k as f64 * e.h())))];
    for c in e.channels() {
        fields.push(Field::new(&c.name, DataType::Float64, false).with_metadata(unit(&c.unit)));
        columns.push(Arc::new(Float64Array::from_iter_values(c.values.iter().copied())));
    }
    let schema: SchemaRef = Arc::new(Schema::new(fields));
    RecordBatch::try_new(schema, columns)
}

/// Writes `e` as a Parquet file (`parquet`) or an Arrow IPC one: the columnar half of
/// [`crate::data::write`], whose errors it returns.
pub(crate) fn write(path: &Path, parquet: bool, e: &Experiment, time: &str) -> Result<()> {
    let write_err = |e: &dyn std::fmt::Display| Error::Write {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    };
    let batch = batch(e, time).map_err(|e| write_err(&e))?;
    match parquet {
        true => {
            use parquet::basic::Compression;
            use parquet::file::properties::WriterProperties;
            let props = WriterProperties::builder()
                .set_compression(Compression::SNAPPY)
                .set_dictionary_enabled(false)
                .set_max_row_group_row_count(Some(ROW_GROUP))
                .build();
            // The writer wants a `Send` sink; the bytes go to the atomic file after.
            let mut w = parquet::arrow::ArrowWriter::try_new(Vec::new(), batch.schema(), Some(props))
                .map_err(|e| write_err(&e))?;
            w.write(&batch).map_err(|e| write_err(&e))?;
            let bytes = w.into_inner().map_err(|e| write_err(&e))?;
            write_atomic(path, |out| out.write_all(&bytes))
        }
        false => write_atomic(path, |out| {
            let mut w = arrow_ipc::writer::FileWriter::try_new(out, &batch.schema())
                .map_err(std::io::Error::other)?;
            // Batches of `BATCH` rows: a reader then decodes one small batch at a time.
            for at in (0..batch.num_rows()).step_by(BATCH) {
                w.write(&batch.slice(at, BATCH.min(batch.num_rows() - at))).map_err(std::io::Error::other)?;
            }
            w.finish().map_err(std::io::Error::other)
        }),
    }
}
