//! The command-line tool's modules: arguments, `fit`, `validate`, `track`, `simulate`, report files.

pub mod args;
pub mod columns;
pub mod fit;
pub mod output;
pub mod plots;
pub mod simulate;
pub mod track;
pub mod validate;
