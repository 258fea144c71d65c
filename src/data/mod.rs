//! Experiment data: named signal channels sampled at `t_k = k h`, validated once on
//! construction.
//!
//! An [`Experiment`] is a sample time plus any number of [`Channel`]s, each a name, a unit
//! and one value per sample. Nothing here knows what a channel means: a model declares the
//! channels it reads and predicts ([`crate::model::GreyBoxModel`]), and a domain view
//! (e.g. [`crate::pmsm::DqView`] for motor logs) gives typed access that errors with the
//! missing channel's name. Units are converted to SI at the edge (the CSV readers), never
//! inside the library.
//!
//! Logs are read by format, chosen by extension ([`Format`]): [`csv`] (plain or gzip) and
//! Parquet or Arrow IPC, both into a [`Table`] under the same checks
//! ([`ReadLimits`], [`TimeSteps`]); [`read_csv`] makes an [`Experiment`] of one by a
//! [`CsvSpec`]; [`write_log`] writes a log in any of the formats. Each item has one home
//! and is re-exported here, so that no format's module depends on the dispatcher.

mod channel;
// The submodules are the crate's, their public items re-exported here, one path each;
// `csv` stays a path of its own: its `read_table_with` is the CSV reader's, this folder's
// reads any format.
pub(crate) mod columnar;
pub mod csv;
mod delimiter;
mod experiment;
pub(crate) mod format;
pub(crate) mod segments;
mod source;
mod spec;
pub(crate) mod staged;
mod table;
mod time;
pub(crate) mod write;

pub(crate) use channel::all_finite;
pub use channel::{Channel, Values};
pub use delimiter::Delimiter;
pub use experiment::{Experiment, MIN_SAMPLES};
pub use format::{Format, read_table, read_table_with, write as write_log};
#[cfg(feature = "parquet")]
pub use format::{read_batches_with, to_record_batch};
pub use segments::{GAP_FACTOR, TimeSegments, TimeWindow, is_gap, time_segments};
#[cfg(feature = "parquet")]
pub use spec::read_spec_batches;
pub use spec::{ColumnMap, CsvSpec, read_csv, read_csv_many};
pub use staged::{Staged, TEMPORARY_PREFIX, interrupt_removing_temporaries, interrupted};
pub use table::{QUOTE_CHARS, ReadLimits, Table};
pub use time::{TIME_TOLERANCE, TimeCheck, TimeSteps};
pub use write::{shortest, write_atomic, write_csv};
