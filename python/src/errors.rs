//! The exceptions of the package, all subclasses of `greybox.Error`, with the command line's
//! messages: the library's error in the words of the command line (its flags, not its
//! field names), as `greybox` prints it after `error: `.

use greybox::Error as E;
use pyo3::PyErr;
use pyo3::create_exception;
use pyo3::exceptions::PyException;

create_exception!(greybox, Error, PyException, "Any error of greybox; the message is the command line's.");
create_exception!(
    greybox,
    DataError,
    Error,
    "A log that cannot be read or used: missing file or column, bad value, non-uniform time, implausible sample time."
);
create_exception!(
    greybox,
    OptionError,
    Error,
    "An invalid option: an unknown keyword, a bad value, a combination the fit cannot honour."
);
create_exception!(
    greybox,
    FitError,
    Error,
    "The fit or simulation failed: diverged, numerical failure, optimiser error."
);

/// The Python exception of a library error, classified by what went wrong (its variant),
/// with the command line's message (`e` already in the command's words).
pub fn to_py(e: E) -> PyErr {
    let message = e.to_string();
    match e {
        E::Io { .. }
        | E::Csv { .. }
        | E::MissingColumn { .. }
        | E::MissingChannel { .. }
        | E::DuplicateChannel { .. }
        | E::NonFinite { .. }
        | E::ImplausibleValue { .. }
        | E::LengthMismatch { .. }
        | E::TooShort { .. }
        | E::NonUniformTime { .. }
        | E::InvalidSampleTime { .. }
        | E::LimitExceeded { .. }
        | E::DuplicateColumn { .. }
        | E::ImplausibleSampleTime { .. }
        | E::Format { .. }
        | E::ColumnType { .. } => DataError::new_err(message),
        E::InvalidOption { .. } | E::InvalidBounds { .. } | E::StartOutsideBounds { .. } => {
            OptionError::new_err(message)
        }
        E::Domain(_) if e.domain::<greybox::pmsm::PmsmError>().is_some() => OptionError::new_err(message),
        E::SimulationDiverged { .. } | E::Numerical { .. } | E::Solver(_) | E::InvalidParameter { .. } => {
            FitError::new_err(message)
        }
        _ => Error::new_err(message),
    }
}

/// An option the Python function does not take (a file output of the command line).
pub fn refused(option: &str, reason: &str) -> PyErr {
    OptionError::new_err(format!("invalid option `{option}`: {reason}"))
}
