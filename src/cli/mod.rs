//! The command-line tool's modules: arguments, `fit`, `validate`, `track`, report files.

pub mod args;
pub mod fit;
pub mod output;
pub mod track;
pub mod validate;
