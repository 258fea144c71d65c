//! A PMSM drive log read and viewed: the reader (CSV, gzip, Parquet, Arrow IPC) with its
//! units, frames and time window, the typed dq view of the channels, and Clarke and Park.

mod build;
pub(super) mod flux_map;
mod options;
mod plausible;
mod reader;
pub(super) mod signals;
mod split;
pub(super) mod transform;
mod views;

pub use options::*;
pub use reader::{LogSource, read_log, read_log_from, read_logs};
pub use split::{DroppedSegment, LogSegments, read_log_segments, read_log_segments_from};
pub(crate) use views::{DqLogs, longest_h, modulator_reference, peak_current};
