//! The command line's parser of the library's enums (`MotorKind`, `HoldChoice`, …, which
//! derive `clap::ValueEnum` under the `cli` feature), and the `--format` of `greybox fit`.

use clap::ValueEnum;
use clap::builder::{PossibleValuesParser, TypedValueParser};

/// Parses a library enum by its value names (and aliases), listing the names in `--help`
/// as `[possible values: …]` without each variant's documentation, which the option's own
/// help already explains (the variants' docs would put every option of `fit --help` on
/// lines of its own).
pub fn listed<E: ValueEnum + Clone + Send + Sync + 'static>() -> impl TypedValueParser<Value = E> {
    let values = E::value_variants().iter().filter_map(E::to_possible_value).map(|p| p.help(None::<&str>));
    PossibleValuesParser::new(values).try_map(|s: String| E::from_str(&s, true))
}

/// What `greybox fit` prints on stdout (`--format`): the aligned table, the JSON report,
/// the table as Markdown.
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    Table,
    Json,
    Markdown,
}
