//! What a fit of issue 33 produced ([`Report`]), the saturation model's exponents checked,
//! and the logs read with one optional channel more.

use crate::Experiment;
use crate::app::LogReading;
use crate::error::{Error, Result};
use crate::pmsm::{CsvOptions, LogSource, SaturationExponents};

/// What a fit of issue 33 produced: its text report, its JSON report, and why it is not to
/// be trusted.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Report {
    /// The text report (what the command line prints).
    pub text: String,
    /// The JSON report (what `--json` writes).
    pub json: String,
    /// The codes of the reasons it is not to be trusted (the command line's exit code 3);
    /// empty when trusted.
    pub untrusted: Vec<String>,
}

impl Report {
    /// The report of `text` and the JSON of `value`, untrusted for `untrusted`.
    pub fn new<T: serde::Serialize>(text: String, value: &T, untrusted: Vec<String>) -> Self {
        Self { text, json: serde_json::to_string_pretty(value).unwrap_or_default(), untrusted }
    }

    /// Whether the fit is to be trusted (`untrusted` empty).
    pub fn trusted(&self) -> bool {
        self.untrusted.is_empty()
    }
}

/// The saturation model's exponents `S,T,U,V` (Hinkkanen et al., IEEE Trans. Ind. Appl.
/// 53(3) 2017) from four integers.
///
/// # Errors
/// [`Error::InvalidOption`] (`--exponents`) unless four integers with `S, T ≥ 1`.
pub fn exponents(values: &[u32]) -> Result<SaturationExponents> {
    match *values {
        [s, t, u, v] if s >= 1 && t >= 1 => Ok(SaturationExponents { s, t, u, v }),
        _ => Err(Error::InvalidOption {
            option: "--exponents".into(),
            reason: format!("{values:?}: give four integers S,T,U,V with S, T ≥ 1, e.g. --exponents 4,2,1,0"),
        }),
    }
}

/// Reads `sources` (files or tables) as a fit does with `reading` and `pole_pairs` (all
/// segments in order, the paths checked first: [`crate::app::read_sources`]), plus the
/// optional column `extra = (column, name, unit)`: carried through
/// ([`crate::pmsm::ColumnNames::extra`]) and offered under the channel name `name` the fit
/// reads, in `unit`.
///
/// # Errors
/// Those of [`crate::app::read_sources`].
pub(super) fn read_with_channel(
    sources: &[LogSource<'_>],
    reading: &LogReading,
    pole_pairs: u32,
    extra: (&str, &str, &str),
) -> Result<Vec<Experiment>> {
    let (column, name, unit) = extra;
    let mut csv = CsvOptions { pole_pairs: Some(pole_pairs), ..reading.csv.clone() };
    csv.columns.extra = vec![column.to_string()];
    crate::app::read_sources(reading, &csv, sources)?
        .into_iter()
        .map(|e| match e.get(column).map(|c| c.values.as_slice().to_vec()) {
            Some(values) if column != name => e.with_channel(crate::data::Channel::new(name, unit, values)),
            _ => Ok(e),
        })
        .collect()
}
