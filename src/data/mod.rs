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
//! Logs are read by format, chosen by extension in [`format`](mod@format): [`csv`] (plain or gzip) and
//! [`columnar`] (Parquet, Arrow IPC), both into a [`Table`] under the same checks
//! ([`ReadLimits`], [`TimeSteps`]); [`read_csv`] makes an [`Experiment`] of one by a
//! [`CsvSpec`]; [`write_log`] writes a log in any of the formats. Each item has one home
//! and is re-exported here, so that no format's module depends on the dispatcher.

mod channel;
pub mod columnar;
pub mod csv;
mod delimiter;
mod experiment;
pub mod format;
pub mod segments;
mod source;
mod spec;
pub mod staged;
mod table;
mod time;
pub mod write;

pub(crate) use channel::all_finite;
pub use channel::{Channel, Values};
pub use delimiter::Delimiter;
pub use experiment::{Experiment, MIN_SAMPLES};
pub use format::{Format, read_table, read_table_with, write as write_log};
#[cfg(feature = "parquet")]
pub use format::{read_batches_with, to_record_batch};
pub use segments::{GAP_FACTOR, TimeWindow, is_gap};
pub use spec::{ColumnMap, CsvSpec, read_csv, read_csv_many};
pub use table::{QUOTE_CHARS, ReadLimits, Table};
pub use time::{TIME_TOLERANCE, TimeCheck, TimeSteps};
