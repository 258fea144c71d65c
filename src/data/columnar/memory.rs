//! Arrow record batches in memory (a table handed over by Python through the Arrow C stream
//! interface) read as a columnar log: the same header, type, null, finiteness, row-limit and
//! time checks as a Parquet or Arrow IPC file.

use std::path::Path;

use arrow_array::RecordBatch;
use arrow_schema::Schema;

use super::arrow_io::{check_rows, collect, header};
use super::check;
use crate::data::table::{ReadLimits, Table};
use crate::data::time::TimeCheck;
use crate::error::Result;

/// Reads the `wanted` columns of Arrow record `batches` in memory (e.g. a table handed over
/// by Python through the Arrow C stream interface, not copied before this conversion to
/// f64) as [`super::arrow_io::read`] reads a file's: the same header, type, null, finiteness, row-limit and
/// time checks, with `name` standing for the path in errors and naming the table.
pub(crate) fn read_batches(
    name: &str,
    schema: &Schema,
    batches: &[RecordBatch],
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    time: TimeCheck,
) -> Result<Table> {
    let path = Path::new(name);
    let (header, index) = header(path, schema, wanted, limits)?;
    let rows: u64 = batches.iter().map(|b| b.num_rows() as u64).sum();
    check_rows(path, rows, limits)?;
    let streaming = time == TimeCheck::Streaming;
    let values = collect(path, batches.iter().cloned().map(Ok), &header, &index, streaming)?;
    let values: Vec<Option<Vec<f64>>> = index.iter().zip(values).map(|(i, c)| i.map(|_| c)).collect();
    let time = streaming.then(|| wanted.first().map_or("", |w| w.0));
    check::rows(path, time, &header, &index, &values)?;
    Ok(Table { name: name.to_string(), header, columns: values })
}
