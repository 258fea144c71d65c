//! The command-line tool's modules: arguments, `fit` and its batch (`fit --each`), `validate`, `track`, `simulate`, report files.
// The flags' doc comments are the command line's `--help` text, written for a terminal
// (units in brackets, `<output>_measured`): rustdoc's link and HTML checks do not apply.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

pub mod args;
pub mod batch;
pub mod columns;
pub mod design;
pub mod errors;
pub mod fit;
pub mod fluxmap;
pub mod mechanics;
pub mod output;
pub mod plots;
pub mod progress;
pub mod pwm_args;
pub mod saturation;
pub mod simulate;
pub mod standstill;
pub mod track;
pub mod validate;
pub mod values;

/// The subcommand `name` with the flags of `T` (e.g. `fit` with [`args::FitArgs`]), as the
/// command line builds it: what [`errors::in_cli_words`] looks flags up in.
pub fn command<T: clap::Args>(name: &'static str) -> clap::Command {
    T::augment_args(clap::Command::new(name))
}

/// The flags `argv` of the subcommand `name` (without the program's and the subcommand's
/// names, e.g. `["log.csv", "-p", "4"]`), parsed into `T` as `greybox NAME ARGV…` parses
/// them: the same defaults, value parsers and messages.
///
/// # Errors
/// clap's error for an unknown flag, a missing or invalid value (its message is the
/// command line's).
pub fn parse<T: clap::Args + clap::FromArgMatches>(
    name: &'static str,
    argv: &[String],
) -> Result<T, clap::Error> {
    let matches = command::<T>(name).no_binary_name(true).try_get_matches_from(argv)?;
    T::from_arg_matches(&matches)
}
