//! `greybox._greybox`: the native half of the Python package `greybox`, thin over the
//! library's command-line layer ([`greybox::cli`]): keyword options arrive as the command
//! line's flags (the Python half turns `dead_time="estimate"` into `--dead-time estimate`)
//! and are parsed by the command line's own parser, so that defaults, checks and messages
//! are the command line's; every fit runs with the GIL released.
//!
//! The Python half (`python/greybox/`) is the public face; this module is private.

mod errors;
mod fit;
mod many;
mod tools;

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
    m.add_function(wrap_pyfunction!(tools::validate, m)?)?;
    m.add_function(wrap_pyfunction!(tools::track, m)?)?;
    m.add_function(wrap_pyfunction!(tools::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(tools::report, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
