//! The command-line tool's modules: arguments, `fit` and its batch (`fit --each`), `validate`, `track`, `simulate`, report files.

pub mod args;
pub mod batch;
pub mod columns;
pub mod errors;
pub mod fit;
pub mod logs;
pub mod output;
pub mod plots;
pub mod simulate;
pub mod track;
pub mod validate;
pub mod values;
