//! The command-line tool's modules: arguments, `fit`, `validate`, report files.

pub mod args;
pub mod fit;
pub mod output;
pub mod validate;
