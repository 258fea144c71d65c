//! A measured flux map read into an experiment with the channels `i_d`, `i_q` \[A\] and
//! `psi_d`, `psi_q` \[V s\] (one point per sample; the sample time means nothing).

use crate::data::csv::read_table_with_missing;
use crate::data::{Channel, Delimiter, Experiment, Format, ReadLimits, TimeCheck, read_table_with};
use crate::error::{Error, Result};
use crate::pmsm::log::reader::LogSource;
use nalgebra::Complex;

type Complex64 = Complex<f64>;
use std::io::Read;
use std::path::Path;

/// The arrays a NumPy flux map (`.npz`) holds: currents and flux linkages as complex dq
/// values (`d + j q`), the layout of motulator's measured maps.
pub const NPZ_ARRAYS: [&str; 2] = ["i_s_dq", "psi_s_dq"];

/// How a flux map's CSV is read: the names of its four columns and its field delimiter
/// (a `.npz` holds the arrays [`NPZ_ARRAYS`] whatever these say). Default `i_d, i_q, psi_d,
/// psi_q` \[A, A, V s, V s\], peak dq, separated by `,`.
#[derive(Clone, Debug, PartialEq)]
pub struct FluxMapColumns {
    /// d-axis current \[A\]. Default `i_d`.
    pub i_d: String,
    /// q-axis current \[A\]. Default `i_q`.
    pub i_q: String,
    /// d-axis flux linkage \[V s\]. Default `psi_d`.
    pub psi_d: String,
    /// q-axis flux linkage \[V s\]. Default `psi_q`.
    pub psi_q: String,
    /// The CSV's field delimiter. Default `,`.
    pub delimiter: Delimiter,
    /// A measured torque \[N m\], read when the header has it (optional). Default `torque`.
    pub torque: String,
}

impl Default for FluxMapColumns {
    fn default() -> Self {
        let [i_d, i_q, psi_d, psi_q] = CHANNELS.map(String::from);
        Self { i_d, i_q, psi_d, psi_q, delimiter: Delimiter::default(), torque: "torque".into() }
    }
}

/// The channels of a flux map read ([`read_flux_map_with`]).
const CHANNELS: [&str; 4] = ["i_d", "i_q", "psi_d", "psi_q"];

/// A flux map read by [`read_flux_map_with`]: the measured points and those left out.
#[derive(Clone, Debug)]
pub struct FluxMapRead {
    /// The points with all four values finite, channels `i_d`, `i_q` \[A\] and `psi_d`,
    /// `psi_q` \[V s\], in the file's order.
    pub map: Experiment,
    /// How many points were left out for a missing value (empty, NaN or ±inf in any of the
    /// four): a measured map's unmeasured points.
    pub skipped: usize,
    /// The 0-based index of the first point left out (a CSV's data row, an `.npz` array's
    /// flat C-order index).
    pub first_skipped: Option<usize>,
    /// The measured torque \[N m\] of the points in `map` (NaN where its cell is missing),
    /// when the table has the column [`FluxMapColumns::torque`]; `None` otherwise, for an
    /// `.npz`, and for a Parquet or Arrow torque column with a missing value.
    pub torque: Option<Vec<f64>>,
}

/// Reads a flux map as [`read_flux_map_with`] does with the default columns, and refuses a
/// point with a missing value instead of leaving it out.
///
/// # Errors
/// Those of [`read_flux_map_with`]; [`Error::NonFinite`] naming the channel and point of a
/// NaN or ±inf.
pub fn read_flux_map(path: impl AsRef<Path>) -> Result<Experiment> {
    let read = read_flux_map_with(path, &FluxMapColumns::default())?;
    match read.first_skipped {
        None => Ok(read.map),
        Some(row) => Err(Error::NonFinite { column: "a flux map's point".into(), row, value: f64::NAN }),
    }
}

/// Reads a flux map: a NumPy `.npz` with the complex128 arrays `i_s_dq` \[A, peak\] and
/// `psi_s_dq` \[V s\] of one shape (any; flattened in C order), or a CSV (gzip detected by
/// its bytes), Parquet or Arrow IPC file with the four `columns` (and the optional torque),
/// one operating point per row. A point with a missing value (an empty CSV cell, NaN, ±inf) is left out and
/// counted, as measured maps mark the points they could not reach.
///
/// # Errors
/// [`Error::Io`] for a file that cannot be opened; [`Error::Format`] for a MATLAB `.mat` file
/// (saying how to convert it), naming the missing array, a dtype that is not complex128, or
/// arrays of different sizes; the CSV reader's errors
/// ([`read_table_with_missing`](crate::data::csv::read_table_with_missing): a missing column
/// listed with the header, a cell that is no number with its line; a columnar file's
/// [`read_table_with`], which refuses a null); [`Error::TooShort`] for
/// fewer than 8 points left (the model has 6 coefficients).
pub fn read_flux_map_with(path: impl AsRef<Path>, columns: &FluxMapColumns) -> Result<FluxMapRead> {
    let path = path.as_ref();
    let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    refuse_matlab(path)?;
    let is_npz = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npz"));
    let ([i_d, i_q, psi_d, psi_q], torque): ([Vec<f64>; 4], Option<Vec<f64>>) = if is_npz {
        let [i, psi] = NPZ_ARRAYS.map(|a| read_npz_array(path, a));
        let (i, psi) = (i?, psi?);
        if i.len() != psi.len() {
            return Err(format_error(
                path,
                format!(
                    "`i_s_dq` has {} points and `psi_s_dq` {}: they must have one shape",
                    i.len(),
                    psi.len()
                ),
            ));
        }
        let flux = [
            i.iter().map(|c| c.re).collect(),
            i.iter().map(|c| c.im).collect(),
            psi.iter().map(|c| c.re).collect(),
            psi.iter().map(|c| c.im).collect(),
        ];
        (flux, None)
    } else {
        let c = columns;
        let wanted = wanted(c);
        let limits = ReadLimits::default();
        let (table, torque) = match Format::of(path) {
            Format::Csv => (read_table_with_missing(path, &wanted, &limits, c.delimiter)?, None),
            // A columnar reader refuses a missing value: the torque is read on its own, and a
            // torque column with a gap is not read (the flux map as before it).
            _ => (
                read_table_with(path, &wanted[..4], &limits, c.delimiter, TimeCheck::Skip)?,
                read_table_with(path, &wanted[4..], &limits, c.delimiter, TimeCheck::Skip)
                    .ok()
                    .and_then(|t| t.columns.into_iter().next().flatten()),
            ),
        };
        let mut columns = table.columns.into_iter();
        let flux = [(); 4].map(|()| columns.next().flatten().unwrap_or_default());
        (flux, columns.next().flatten().or(torque))
    };
    finish(name, [i_d, i_q, psi_d, psi_q], torque)
}

/// [`read_flux_map_with`] of a file or (feature `parquet`) an Arrow table in memory (a
/// pyarrow, polars or pandas table handed over by Python): a table's columns read as a
/// Parquet file's, the map named by the table's name.
///
/// # Errors
/// Those of [`read_flux_map_with`] (a table's, as a columnar file's, naming its name).
pub fn read_flux_map_from(source: LogSource<'_>, columns: &FluxMapColumns) -> Result<FluxMapRead> {
    match source {
        LogSource::Path(path) => read_flux_map_with(path, columns),
        #[cfg(feature = "parquet")]
        LogSource::Arrow { name, schema, batches } => {
            let wanted = wanted(columns);
            let limits = ReadLimits::default();
            let read = |w: &[(&str, bool)]| {
                crate::data::read_batches_with(name, schema, batches, w, &limits, TimeCheck::Skip)
            };
            let table = read(&wanted[..4])?;
            // As from a columnar file: a torque column with a gap is not read.
            let torque = read(&wanted[4..]).ok().and_then(|t| t.columns.into_iter().next().flatten());
            let mut columns = table.columns.into_iter();
            let flux = [(); 4].map(|()| columns.next().flatten().unwrap_or_default());
            finish(name.to_string(), flux, torque)
        }
    }
}

/// The columns a map's table is read by: the four of the flux map (required) and the
/// torque (optional).
fn wanted(c: &FluxMapColumns) -> [(&str, bool); 5] {
    [
        (c.i_d.as_str(), true),
        (c.i_q.as_str(), true),
        (c.psi_d.as_str(), true),
        (c.psi_q.as_str(), true),
        (c.torque.as_str(), false),
    ]
}

/// The map `name` of the points whose four values `[i_d, i_q, psi_d, psi_q]` are finite,
/// and their `torque`.
///
/// # Errors
/// [`Error::TooShort`] for fewer than 8 points kept.
fn finish(
    name: String,
    [i_d, i_q, psi_d, psi_q]: [Vec<f64>; 4],
    torque: Option<Vec<f64>>,
) -> Result<FluxMapRead> {
    let kept: Vec<usize> =
        (0..i_d.len()).filter(|&k| [&i_d, &i_q, &psi_d, &psi_q].iter().all(|v| v[k].is_finite())).collect();
    let first_skipped = (0..i_d.len()).find(|k| kept.binary_search(k).is_err());
    let skipped = i_d.len() - kept.len();
    if kept.len() < 8 {
        return Err(Error::TooShort { name, len: kept.len(), min: 8 });
    }
    let channels = CHANNELS
        .iter()
        .zip(["A", "A", "V s", "V s"])
        .zip([i_d, i_q, psi_d, psi_q])
        .map(|((n, u), v)| Channel::new(*n, u, kept.iter().map(|&k| v[k]).collect()))
        .collect();
    let torque = torque.map(|t| kept.iter().map(|&k| t[k]).collect());
    Ok(FluxMapRead { map: Experiment::try_new(name, 1.0, channels)?, skipped, first_skipped, torque })
}

/// Refuses a MATLAB `.mat` file (by its extension or its header text, v4 to v7.3) with how
/// to convert it.
fn refuse_matlab(path: &Path) -> Result<()> {
    let mut head = [0u8; 128];
    let n = std::fs::File::open(path).and_then(|mut f| f.read(&mut head)).unwrap_or(0);
    let by_header = head[..n].windows(6).any(|w| w == b"MATLAB");
    let by_name = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("mat"));
    if !(by_header || by_name) {
        return Ok(());
    }
    Err(format_error(
        path,
        "a MATLAB .mat file: greybox reads a flux map as a NumPy .npz (complex arrays i_s_dq, psi_s_dq) or a CSV \
         with one point per row; write one from MATLAB with writetable(table(id(:), iq(:), psid(:), psiq(:), \
         'VariableNames', {'i_d', 'i_q', 'psi_d', 'psi_q'}), 'map.csv') or from Python with scipy.io.loadmat and \
         numpy.savez"
            .into(),
    ))
}

fn format_error(path: &Path, message: String) -> Error {
    Error::Format { path: path.to_path_buf(), message }
}

/// One complex128 array of an `.npz` (a zip of `.npy` files, stored or deflated).
fn read_npz_array(path: &Path, array: &str) -> Result<Vec<Complex64>> {
    let io = |source: std::io::Error| Error::Io { path: path.to_path_buf(), source };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut zip = zip::ZipArchive::new(file)
        .map_err(|e| format_error(path, format!("not a NumPy .npz (zip) archive: {e}")))?;
    let mut entry = zip.by_name(&format!("{array}.npy")).map_err(|_| {
        format_error(path, format!("no array `{array}`: a flux map needs the arrays {NPZ_ARRAYS:?}"))
    })?;
    let mut bytes = Vec::new();
    entry.read_to_end(&mut bytes).map_err(io)?;
    let npy =
        npyz::NpyFile::new(&bytes[..]).map_err(|e| format_error(path, format!("array `{array}`: {e}")))?;
    let dtype = npy.dtype();
    let is_c128 = matches!(&dtype, npyz::DType::Plain(t) if t.type_char() == npyz::TypeChar::Complex && t.size_field() == 16);
    if !is_c128 {
        return Err(format_error(
            path,
            format!("array `{array}` has dtype {}, not complex128 (`d + j q` values)", dtype.descr()),
        ));
    }
    npy.into_vec::<Complex64>().map_err(|e| format_error(path, format!("array `{array}`: {e}")))
}
