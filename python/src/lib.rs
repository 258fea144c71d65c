//! `greybox._greybox`: the native half of the Python package `greybox`. The fits (`fit`,
//! `fit_records`), `track`, `validate`, `simulate` and the reports of issue 33 (`fluxmap`,
//! `saturation`, `standstill`, `mechanics`) are thin over the library's application layer
//! ([`greybox::app`]): the keyword options arrive as a dict, each converted once into the
//! typed request ([`request`], [`track`], [`validate`], [`simulate`], [`tools`]; the logs'
//! reading by [`reading`]) and every error put in the keywords' words ([`words`]). The
//! library is built without its command line (no `cli` feature). Every run releases the GIL.
//!
//! The Python half (`python/greybox/`) is the public face; this module is private.

mod errors;
mod fit;
mod keyword;
mod many;
mod reading;
mod request;
mod simulate;
mod tools;
mod track;
mod validate;
mod words;

use pyo3::prelude::*;

/// The native module: the functions of [`fit`], [`many`] and [`tools`] and the exception
/// classes of [`errors`].
#[pymodule]
fn _greybox(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<errors::Error>())?;
    m.add("DataError", py.get_type::<errors::DataError>())?;
    m.add("OptionError", py.get_type::<errors::OptionError>())?;
    m.add("FitError", py.get_type::<errors::FitError>())?;
    m.add_class::<fit::NativeFit>()?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(many::fit_records, m)?)?;
    m.add_function(wrap_pyfunction!(many::summary_columns, m)?)?;
    m.add_function(wrap_pyfunction!(many::log_names, m)?)?;
    m.add_function(wrap_pyfunction!(many::expand_logs, m)?)?;
    m.add_function(wrap_pyfunction!(validate::validate, m)?)?;
    m.add_function(wrap_pyfunction!(track::track, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(tools::report, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("INNOVATION_RATIO_LIMIT", greybox::online::INNOVATION_RATIO_LIMIT)?;
    Ok(())
}
