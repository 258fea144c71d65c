//! # greybox
//!
//! Grey-box estimation of the electrical parameters of permanent-magnet synchronous
//! motors from drive logs.
#![warn(missing_docs)]

pub mod data;
pub mod error;
pub mod estimate;
pub mod model;
pub mod pmsm;
pub mod simulate;

pub use data::csv::{CsvOptions, read_csv};
pub use data::{Experiment, Signals};
pub use error::{Error, Result};
