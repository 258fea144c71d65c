//! The command line's parser of the library's enums (`MotorKind`, `HoldChoice`, …, which
//! derive `clap::ValueEnum` under the `cli` feature).

use crate::pmsm::{Dynamics, MotorKind};
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

/// The estimation method (`--method`): prediction error, or instrumental variables where
/// the logged voltage's noise biases it (`auto`), prediction error (`pem`), linear least
/// squares (`ls`), instrumental variables (`iv`).
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MethodArg {
    Auto,
    Pem,
    Ls,
    Iv,
}

/// Which voltage drives the model (`--voltage`): the measured terminal voltage (`actual`)
/// or the controller's reference (`reference`).
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum VoltageArg {
    Actual,
    Reference,
}

/// The machine model and its equations (`--model`): surface or interior magnets, dynamic
/// (chosen from the sample time) or the steady-state equations of slow logs.
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    Spm,
    Ipm,
    SpmSteady,
    IpmSteady,
}

impl ModelArg {
    /// The machine.
    pub fn kind(self) -> MotorKind {
        match self {
            Self::Spm | Self::SpmSteady => MotorKind::Spm,
            Self::Ipm | Self::IpmSteady => MotorKind::Ipm,
        }
    }

    /// Which equations: chosen from the sample time, or the steady-state ones.
    pub fn dynamics(self) -> Dynamics {
        match self {
            Self::Spm | Self::Ipm => Dynamics::Auto,
            Self::SpmSteady | Self::IpmSteady => Dynamics::Steady,
        }
    }
}
