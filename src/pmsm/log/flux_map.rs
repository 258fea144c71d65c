//! A measured flux map read into an experiment with the channels `i_d`, `i_q` \[A\] and
//! `psi_d`, `psi_q` \[V s\] (one point per sample; the sample time means nothing).

use crate::data::{Channel, Delimiter, Experiment, ReadLimits, TimeCheck, read_table_with};
use crate::error::{Error, Result};
use nalgebra::Complex;

type Complex64 = Complex<f64>;
use std::io::Read;
use std::path::Path;

/// The arrays a NumPy flux map (`.npz`) holds: currents and flux linkages as complex dq
/// values (`d + j q`), the layout of motulator's measured maps.
pub const NPZ_ARRAYS: [&str; 2] = ["i_s_dq", "psi_s_dq"];

/// Reads a flux map: a NumPy `.npz` with the complex128 arrays `i_s_dq` \[A, peak\] and
/// `psi_s_dq` \[V s\] of one shape (any; flattened in C order), or a CSV (gzip with `.gz`)
/// with the columns `i_d`, `i_q`, `psi_d`, `psi_q`, one operating point per row.
///
/// # Errors
/// [`Error::Io`] for a file that cannot be opened; [`Error::Format`] naming the missing
/// array, a dtype that is not complex128, or arrays of different sizes; the CSV reader's
/// errors ([`read_table_with`]); [`Error::NonFinite`] naming the array and point of a NaN;
/// [`Error::TooShort`] for fewer than 8 points (the model has 6 coefficients).
pub fn read_flux_map(path: impl AsRef<Path>) -> Result<Experiment> {
    let path = path.as_ref();
    let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let is_npz = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npz"));
    let [i_d, i_q, psi_d, psi_q] = if is_npz {
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
        [
            i.iter().map(|c| c.re).collect(),
            i.iter().map(|c| c.im).collect(),
            psi.iter().map(|c| c.re).collect(),
            psi.iter().map(|c| c.im).collect(),
        ]
    } else {
        let wanted = [("i_d", true), ("i_q", true), ("psi_d", true), ("psi_q", true)];
        let table =
            read_table_with(path, &wanted, &ReadLimits::default(), Delimiter::default(), TimeCheck::Skip)?;
        let mut columns = table.columns.into_iter().map(Option::unwrap_or_default);
        [(); 4].map(|()| columns.next().unwrap_or_default())
    };
    let names = ["i_d", "i_q", "psi_d", "psi_q"];
    for (column, values) in names.iter().zip([&i_d, &i_q, &psi_d, &psi_q]) {
        if let Some(row) = values.iter().position(|v: &f64| !v.is_finite()) {
            return Err(Error::NonFinite { column: (*column).into(), row, value: values[row] });
        }
    }
    if i_d.len() < 8 {
        return Err(Error::TooShort { name, len: i_d.len(), min: 8 });
    }
    let units = ["A", "A", "V s", "V s"];
    let channels = names
        .iter()
        .zip(units)
        .zip([i_d, i_q, psi_d, psi_q])
        .map(|((n, u), v)| Channel::new(*n, u, v))
        .collect();
    Experiment::try_new(name, 1.0, channels)
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
