//! The keywords of how logs are read (columns, units, frames, window, limits, segments),
//! shared by the Python functions that read logs (`fit`, `fit_many`, `track`): each
//! converted once, by the same words the command line accepts, a wrong one refused naming
//! the keyword; and each function's keywords ([`Keywords`]): the error of one it does not
//! take, with the closest known ones.

use crate::errors::OptionError;
use crate::keyword::Value;
use greybox::app::LogReading;
use greybox::data::Delimiter;
use greybox::pmsm::{ColumnNames, CsvOptions, DqSource};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The keywords of a log's reading, in the order `--help` lists their flags.
pub const READING_KEYWORDS: &[&str] = &[
    "col_t",
    "col_ud",
    "col_uq",
    "col_id",
    "col_iq",
    "col_w",
    "col_theta",
    "col_ud_ref",
    "col_uq_ref",
    "col_i_abc",
    "col_u_abc",
    "columns",
    "speed_unit",
    "angle_unit",
    "speed_frame",
    "negate_speed",
    "current_scale",
    "voltage_scale",
    "dq_from_phases",
    "time_unit",
    "from",
    "to",
    "split_gaps",
    "force",
    "max_line_bytes",
    "max_fields",
    "max_rows",
    "delimiter",
];

/// The reading's keywords as they are given ([`ReadingKeys::take`]), then the reading
/// ([`ReadingKeys::finish`]).
pub struct ReadingKeys {
    csv: CsvOptions,
    names: ColumnNames,
    renamed: Vec<String>,
    columns: Option<Vec<(String, String)>>,
    dq_from_phases: bool,
    split_gaps: bool,
}

impl ReadingKeys {
    /// From the reader's options `csv` (the command line's defaults).
    pub fn new(csv: CsvOptions) -> Self {
        Self {
            csv,
            names: ColumnNames::default(),
            renamed: Vec::new(),
            columns: None,
            dq_from_phases: false,
            split_gaps: false,
        }
    }

    /// Takes keyword `key` with its value `x` if it is one of the reading's; `false` if not.
    ///
    /// Errors: `OptionError` naming the keyword for a bad value.
    pub fn take(&mut self, key: &str, x: &Value<'_, '_>) -> PyResult<bool> {
        match key {
            "col_t" | "col_ud" | "col_uq" | "col_id" | "col_iq" | "col_w" | "col_theta" | "col_ud_ref"
            | "col_uq_ref" => {
                let standard =
                    greybox::app::columns::RENAMEABLE.iter().find(|(_, o)| *o == key).map(|(s, _)| *s);
                if let Some(slot) = standard.and_then(|s| self.names.column_mut(s)) {
                    *slot = x.text()?;
                }
                self.renamed.push(key.to_string());
            }
            "col_i_abc" => {
                [self.names.i_a, self.names.i_b, self.names.i_c] = x.three()?;
                self.renamed.push(key.to_string());
            }
            "col_u_abc" => {
                [self.names.u_a, self.names.u_b, self.names.u_c] = x.three()?;
                self.renamed.push(key.to_string());
            }
            "columns" => self.columns = Some(column_map(x)?),
            "speed_unit" => self.csv.speed_unit = x.choice()?,
            "angle_unit" => self.csv.angle_unit = x.choice()?,
            "speed_frame" => self.csv.speed_frame = x.choice()?,
            "negate_speed" => self.csv.negate_speed = x.flag()?,
            "current_scale" => self.csv.current_scale = x.choice()?,
            "voltage_scale" => self.csv.voltage_scale = x.choice()?,
            "dq_from_phases" => self.dq_from_phases = x.flag()?,
            "time_unit" => self.csv.time_unit = x.choice()?,
            "from" => self.csv.window.from = x.optional_number()?,
            "to" => self.csv.window.to = x.optional_number()?,
            "split_gaps" => self.split_gaps = x.flag()?,
            "force" => self.csv.force = x.flag()?,
            "max_line_bytes" => self.csv.limits.max_line_bytes = x.count()?,
            "max_fields" => self.csv.limits.max_fields = x.count()?,
            "max_rows" => self.csv.limits.max_rows = x.count()?,
            "delimiter" => {
                self.csv.delimiter = x.parsed(|s| s.parse::<Delimiter>().map_err(|e| e.to_string()))?
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// The reading of the keywords taken.
    ///
    /// Errors: `OptionError` for `columns` with a `col_*` keyword.
    pub fn finish(mut self) -> PyResult<LogReading> {
        if let Some(map) = self.columns {
            if let Some(first) = self.renamed.first() {
                return Err(OptionError::new_err(format!(
                    "columns: not together with {first} (name every column in `columns`, or each in its col_* keyword)"
                )));
            }
            for (standard, name) in map {
                if let Some(slot) = self.names.column_mut(&standard) {
                    *slot = name;
                }
            }
        }
        self.csv.columns = self.names;
        self.csv.source = if self.dq_from_phases { DqSource::Phases } else { DqSource::Dq };
        Ok(LogReading { csv: self.csv, split_gaps: self.split_gaps })
    }
}

/// `columns={"id": "Id", …}`: standard names (those of [`ColumnNames::STANDARD`]) to
/// header names, each standard name once.
fn column_map(x: &Value<'_, '_>) -> PyResult<Vec<(String, String)>> {
    let Ok(map) = x.v.cast::<PyDict>() else {
        return Err(x.err("expected a dict of standard name to header name, e.g. {\"id\": \"Id\"}"));
    };
    let mut out: Vec<(String, String)> = Vec::new();
    for (k, v) in map.iter() {
        let standard: String = Value { key: x.key, v: &k }.text()?;
        let name: String = Value { key: x.key, v: &v }.text()?;
        if !ColumnNames::STANDARD.contains(&standard.as_str()) {
            return Err(x.err(&format!(
                "`{standard}` is not a standard column name; one of {}",
                ColumnNames::STANDARD.join(", ")
            )));
        }
        if name.is_empty() {
            return Err(x.err(&format!("the header name of `{standard}` is empty")));
        }
        out.push((standard, name));
    }
    Ok(out)
}

/// The keywords of a Python function that runs a command: its own (`own`), the reading's
/// where it reads logs, and the command line's file outputs it refuses.
pub struct Keywords {
    /// The command (`fit`, `track`, …).
    pub command: &'static str,
    /// The page that documents its flags.
    pub doc: &'static str,
    /// An example keyword for the message of an unknown one.
    pub example: &'static str,
    /// Its own keywords.
    pub own: &'static [&'static str],
    /// Whether it takes the reading's keywords ([`READING_KEYWORDS`]).
    pub reading: bool,
    /// The command line's file outputs, which the function does not write.
    pub outputs: &'static [&'static str],
    /// What the function returns instead of writing them.
    pub returns: &'static str,
}

impl Keywords {
    /// The error of `key`, which no option of the command takes: a file output refused
    /// (what the function returns instead), or an unknown keyword with the closest known
    /// ones.
    pub fn not_taken(&self, key: &str) -> PyErr {
        if self.outputs.contains(&key) {
            return crate::errors::refused(
                key,
                &format!("the Python functions write no files: {}", self.returns),
            );
        }
        let reading: &[&str] = if self.reading { READING_KEYWORDS } else { &[] };
        let close: Vec<&str> = self
            .own
            .iter()
            .chain(reading)
            .chain(self.outputs)
            .copied()
            .filter(|k| distance(k, key) <= 2)
            .collect();
        let hint = if close.is_empty() {
            format!(
                "the keywords are the flags of `greybox {}` ({}), e.g. {}",
                self.command, self.doc, self.example
            )
        } else {
            format!("did you mean {}?", close.join(" or "))
        };
        OptionError::new_err(format!("unknown keyword `{key}`: {hint}"))
    }
}

/// Levenshtein distance of two short names.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}
