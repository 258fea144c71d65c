//! The command-line tool's modules: arguments, `fit`, `validate`, `track`, `simulate`, report files.

pub mod args;
pub mod columns;
pub mod errors;
pub mod fit;
pub mod logs;
pub mod output;
pub mod plots;
pub mod simulate;
pub mod track;
pub mod validate;
