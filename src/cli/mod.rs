//! The command-line tool's modules: arguments, `fit`, `validate`.

pub mod args;
pub mod fit;
