//! The crate's one error type.
//!
//! Every variant carries what went wrong and where: the column and row of a log, the
//! parameter by name, the experiment and sample of a simulation. User input never
//! panics; it ends up in one of these variants.

use std::path::PathBuf;

/// Everything that can go wrong in greybox.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A file (e.g. the JSON report) could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A CSV file is malformed (bad field, ragged row, unparsable number).
    #[error("{path}: line {line}: {message}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number in the file (the header is line 1).
        line: u64,
        /// What is wrong.
        message: String,
    },
    /// A required column is not in a log's header.
    #[error("{path}: missing column `{column}` (header has: {available})")]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The column name that was looked for.
        column: String,
        /// The header's column names, comma separated.
        available: String,
    },
    /// An experiment lacks a channel that a model or view reads.
    #[error("experiment `{experiment}` has no channel `{channel}` (it has: {available})")]
    MissingChannel {
        /// Experiment name.
        experiment: String,
        /// The channel that was looked for.
        channel: String,
        /// The experiment's channel names, comma separated.
        available: String,
    },
    /// Two channels of one experiment share a name.
    #[error("experiment `{experiment}` has two channels named `{channel}`")]
    DuplicateChannel {
        /// Experiment name.
        experiment: String,
        /// The repeated channel name.
        channel: String,
    },
    /// A signal holds NaN or ±Inf.
    #[error("signal `{column}` is not finite at row {row} (value {value})")]
    NonFinite {
        /// Signal (column) name.
        column: String,
        /// 0-based sample index (data row, header excluded).
        row: usize,
        /// The offending value.
        value: f64,
    },
    /// Two signals of one experiment have different lengths.
    #[error("signal `{column}` has {found} samples, expected {expected}")]
    LengthMismatch {
        /// Signal (column) name.
        column: String,
        /// Length of the reference signal.
        expected: usize,
        /// Length of this signal.
        found: usize,
    },
    /// An experiment has fewer samples than an estimate needs.
    #[error("experiment `{name}` has {len} samples; at least {min} are needed")]
    TooShort {
        /// Experiment name.
        name: String,
        /// Number of samples found.
        len: usize,
        /// Minimum number of samples.
        min: usize,
    },
    /// The time column is not uniformly sampled.
    #[error(
        "time column `{column}` is not uniform at row {row}: step {dt:e} s, expected {expected:e} s (relative tolerance {tolerance:e}){}",
        if *.gap { GAP_HINT } else { "" }
    )]
    NonUniformTime {
        /// Time column name.
        column: String,
        /// 0-based data row where the step deviates (the step from row−1 to row).
        row: usize,
        /// The step found \[s\].
        dt: f64,
        /// The mean step \[s\].
        expected: f64,
        /// Relative tolerance applied.
        tolerance: f64,
        /// Whether the step is a gap (`data::is_gap`: not positive, or longer than 1.5 times
        /// the mean step), set where the error is made; the message then suggests
        /// `--split-gaps`.
        gap: bool,
    },
    /// The sample time is not a positive finite number.
    #[error("sample time h must be positive and finite, got {h} s")]
    InvalidSampleTime {
        /// The value given \[s\].
        h: f64,
    },
    /// An error of a domain layer built on the generic ones, e.g. a motor's
    /// [`crate::pmsm::PmsmError`]; its message is the layer's. [`Error::domain`] gives it
    /// back typed.
    #[error(transparent)]
    Domain(Box<dyn std::error::Error + Send + Sync + 'static>),
    /// A parameter value is unusable (non-finite, non-positive where it must be positive).
    #[error("parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name, e.g. `l_s`.
        name: String,
        /// The value.
        value: f64,
        /// Why it is unusable.
        reason: String,
    },
    /// A parameter's bounds are empty, non-finite where they may not be, or exclude zero-free ranges.
    #[error("parameter `{name}`: invalid bounds [{lower}, {upper}]: {reason}")]
    InvalidBounds {
        /// Parameter name.
        name: String,
        /// Lower bound.
        lower: f64,
        /// Upper bound.
        upper: f64,
        /// Why they are invalid.
        reason: String,
    },
    /// The start value of a parameter lies outside its bounds.
    #[error("start value of parameter `{name}` = {value} lies outside its bounds [{lower}, {upper}]")]
    StartOutsideBounds {
        /// Parameter name.
        name: String,
        /// Start value.
        value: f64,
        /// Lower bound.
        lower: f64,
        /// Upper bound.
        upper: f64,
    },
    /// The model simulation produced a non-finite state.
    #[error(
        "simulation of experiment `{experiment}` diverged at sample {sample} (state not finite) with {parameters}"
    )]
    SimulationDiverged {
        /// Experiment name.
        experiment: String,
        /// 0-based sample index where the state first became non-finite.
        sample: usize,
        /// The parameter values, `name = value` comma separated.
        parameters: String,
    },
    /// A numerical step failed (singular matrix, failed decomposition).
    #[error("numerical failure in {context}: {reason}")]
    Numerical {
        /// Where it happened.
        context: String,
        /// What happened.
        reason: String,
    },
    /// An option or argument is inconsistent (wrong length, unknown name).
    #[error("invalid option `{option}`: {reason}")]
    InvalidOption {
        /// The option.
        option: String,
        /// Why it is invalid.
        reason: String,
    },
    /// The optimiser failed for a reason other than the ones above.
    #[error("optimiser failed: {0}")]
    Solver(String),
    /// A file exceeds one of the read limits ([`crate::data::ReadLimits`]); the read
    /// stopped there, before buffering more.
    #[error("{path}: line {line}: {what} exceeds the read limit `{limit}` = {max}")]
    LimitExceeded {
        /// The file.
        path: PathBuf,
        /// 1-based line number where the limit was passed (the header is line 1).
        line: u64,
        /// What is too large, e.g. `line longer than 1048576 bytes`.
        what: String,
        /// The limit's field name in [`crate::data::ReadLimits`].
        limit: String,
        /// The limit's value.
        max: u64,
    },
    /// A column the read wants appears more than once in the header.
    #[error("{path}: column `{column}` appears twice in the header, as columns {first} and {second}")]
    DuplicateColumn {
        /// The file.
        path: PathBuf,
        /// The repeated header name.
        column: String,
        /// 1-based position of its first occurrence.
        first: usize,
        /// 1-based position of its second occurrence.
        second: usize,
    },
    /// A log's sample time is outside the plausible range (a unit mistake, e.g. a time
    /// column in ms read as s); `force` skips this check.
    #[error(
        "{path}: sample time h = {h:e} s is outside the plausible range [{min:e} s, {max:e} s] ({hint}`--force` skips the plausibility limits)"
    )]
    ImplausibleSampleTime {
        /// The log.
        path: PathBuf,
        /// The sample time found \[s\].
        h: f64,
        /// Smallest plausible h \[s\].
        min: f64,
        /// Largest plausible h \[s\].
        max: f64,
        /// What would explain it, ending in `; `: the time unit that would make h plausible
        /// (`the time column in ms? --time-unit ms gives h = 1e-4 s; `), or a question.
        hint: String,
    },
    /// A value far beyond what a drive logs (a corrupt cell, a column in other units):
    /// a speed beyond ±1e6 rad/s, a current beyond ±1e6 A, a voltage beyond ±1e7 V, in SI
    /// units after the unit options; `force` skips this check.
    #[error(
        "signal `{column}` is {value:e} {unit} at row {row}, beyond the plausible ±{limit:e} {unit} (a corrupt cell, or a column in other units? `--force` skips the plausibility limits)"
    )]
    ImplausibleValue {
        /// The log's column (a dq channel of a log read from its phase columns: with
        /// those columns, `id (from ia, ib, ic)`).
        column: String,
        /// 0-based sample index (data row, header excluded).
        row: usize,
        /// The value \[SI\].
        value: f64,
        /// The plausible magnitude \[SI\].
        limit: f64,
        /// Its unit.
        unit: String,
    },
    /// A columnar log (Parquet, Arrow IPC) that cannot be read or written: a malformed
    /// file, a missing value (null) in a wanted column, or a build without the cargo
    /// feature `parquet`.
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the column and row where there is one.
        message: String,
    },
    /// A wanted column of a columnar log whose type is not a number.
    #[error("{path}: column `{column}` holds {found}, not numbers (integers or floating point)")]
    ColumnType {
        /// The file.
        path: PathBuf,
        /// The column's name.
        column: String,
        /// Its type, e.g. `Utf8`.
        found: String,
    },
}

impl Error {
    /// The domain layer's error of type `T` inside an [`Error::Domain`], if it is one: e.g.
    /// `err.domain::<greybox::pmsm::PmsmError>()`.
    pub fn domain<T: std::error::Error + 'static>(&self) -> Option<&T> {
        match self {
            Self::Domain(e) => e.downcast_ref::<T>(),
            _ => None,
        }
    }
}

/// Short for `std::result::Result<T, greybox::Error>`.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Recovers a greybox error that travelled through argmin's `anyhow`-based error type.
    pub(crate) fn from_argmin(e: argmin::core::Error) -> Self {
        match e.downcast::<Error>() {
            Ok(err) => err,
            Err(other) => Error::Solver(other.to_string()),
        }
    }
}

/// The end of [`Error::NonUniformTime`]'s message for a step that is a gap.
const GAP_HINT: &str = "; this is a gap (a step back or longer than 1.5 h): `--split-gaps` (the reader's \
                        `read_log_segments`) splits the log there into segments fitted jointly";
