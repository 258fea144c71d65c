//! Columnar logs: Parquet and Arrow IPC (Feather v2) files, read into the same [`Table`](super::csv::Table)
//! as a CSV log and written from an [`Experiment`](super::Experiment), chosen by the file's extension.
//!
//! The Arrow and Parquet code is behind the cargo feature `parquet` (on in the default
//! `cli` feature); without it these files give [`Error::Format`](crate::Error::Format) naming the feature. A
//! column of any integer or floating-point type reads as f64 (64-bit integers beyond 2⁵³
//! round to the nearest f64); any other type is [`Error::ColumnType`](crate::Error::ColumnType) naming the column.
//! The checks are those of the CSV reader: the header's ([`crate::data::csv::read_table_with`]),
//! finite values in the wanted columns ([`Error::NonFinite`](crate::Error::NonFinite) naming column and row) and a
//! time column that passes [`crate::data::TimeSteps`], in row order (unless
//! [`read_table_with`](super::read_table_with) is told [`TimeCheck::Skip`](super::TimeCheck::Skip)).
//!
//! The format is chosen by extension in [`super::format`], whose dispatchers this module
//! re-exports under their former paths.

#[cfg(feature = "parquet")]
pub(super) mod arrow_io;
#[cfg(feature = "parquet")]
mod budget;
#[cfg(feature = "parquet")]
mod check;
#[cfg(feature = "parquet")]
mod ipc_scan;
#[cfg(feature = "parquet")]
pub(super) mod memory;
