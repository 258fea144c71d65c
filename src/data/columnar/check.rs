//! The row checks of a columnar read, in the order the CSV reader applies them row by row.

use std::path::Path;

use crate::data::channel::all_finite;
use crate::data::table::experiment_name;
use crate::data::time::TimeSteps;
use crate::error::{Error, Result};

/// Checks the wanted columns `values` (in request order, `None` when absent; the first the
/// time column, named `time`) as the CSV reader checks its rows: the first NaN/Inf and the
/// first bad time step, whichever comes first in row order (a row's time column first).
/// With `time` `None` ([`crate::data::TimeCheck::Skip`]) the time column's steps are not
/// checked, and its values are checked as those of any other column.
///
/// # Errors
/// [`Error::NonFinite`] naming `header[index[j]]` and the row; the errors of
/// [`TimeSteps::push`]; [`Error::TooShort`] for no rows.
pub(super) fn rows(
    path: &Path,
    time: Option<&str>,
    header: &[String],
    index: &[Option<usize>],
    values: &[Option<Vec<f64>>],
) -> Result<()> {
    let n = values.iter().flatten().map(Vec::len).next().unwrap_or(0);
    if n == 0 {
        return Err(Error::TooShort { name: experiment_name(path), len: 0, min: 1 });
    }
    // First non-finite value of the other columns (of all, time unchecked), by (row, column).
    let bad = values
        .iter()
        .zip(index)
        .enumerate()
        .skip(usize::from(time.is_some()))
        .filter_map(|(j, (v, i))| {
            let (v, i) = (v.as_ref()?, (*i)?);
            let row = (!all_finite(v)).then(|| v.iter().position(|x| !x.is_finite())).flatten()?;
            Some((row, j, i, v[row]))
        })
        .min_by_key(|&(row, j, ..)| (row, j));
    // The time column up to and including that row (its time is checked first).
    if let (Some(time), Some(t)) = (time, values.first().and_then(Option::as_ref)) {
        let end = bad.map_or(n, |(row, ..)| row + 1);
        let mut steps = TimeSteps::new(time);
        steps.push_all(&t[..end.min(t.len())])?;
    }
    match bad {
        Some((row, _, i, value)) => Err(Error::NonFinite { column: header[i].clone(), row, value }),
        None => Ok(()),
    }
}
