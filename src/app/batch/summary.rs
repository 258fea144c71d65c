//! The batch summary: one record per log, built once from its fit or its error, written as
//! CSV (one row per log, a column per figure) and JSON, and printed as a table.

use crate::pmsm::PmsmFit;
use crate::report::eng::{UnitScale, decimals_for, display_unit};
use serde::{Deserialize, Deserializer, Serialize};
use std::path::Path;

/// How a log's fit ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Fitted, converged, no untrusted warning.
    Ok,
    /// Fitted, but not converged or with an untrusted warning (the fit's `trusted()`).
    Untrusted,
    /// Could not be read or fitted.
    Failed,
}

// JSON writes a non-finite number as null: read back as NaN (the summary shows neither).
fn nan_if_null<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

fn nan_if_null_2<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    Ok(<[Option<f64>; 2]>::deserialize(d)?.map(|v| v.unwrap_or(f64::NAN)))
}

fn nan_if_null_pairs<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<(String, f64)>, D::Error> {
    let v = Vec::<(String, Option<f64>)>::deserialize(d)?;
    Ok(v.into_iter().map(|(n, f)| (n, f.unwrap_or(f64::NAN))).collect())
}

impl Status {
    fn word(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::Untrusted => "untrusted",
            Self::Failed => "failed",
        }
    }
}

/// An estimate with its standard error and 95 % interval, in the library's unit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Quantity {
    /// Symbol, e.g. `r_s`, `k_t`, `t_winding`.
    pub name: String,
    /// Unit, as the library spells it (`ohm`, `H`, `V s/rad`).
    pub unit: String,
    /// Estimate \[unit\].
    #[serde(deserialize_with = "nan_if_null")]
    pub value: f64,
    /// Standard error \[unit\].
    #[serde(deserialize_with = "nan_if_null")]
    pub std_error: f64,
    /// 95 % interval \[unit\]: the report's (for a derived quantity
    /// [`DerivedEstimate::interval`](crate::model::DerivedEstimate::interval) at the fit's
    /// quantile).
    #[serde(deserialize_with = "nan_if_null_2")]
    pub ci95: [f64; 2],
    /// Held at its start or given value (no standard error).
    pub fixed: bool,
}

/// A warning of a fit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct WarningRecord {
    /// Short code, e.g. `not_converged`.
    pub code: String,
    /// What it means.
    pub message: String,
    /// Whether it makes the fit untrusted.
    pub untrusted: bool,
}

/// The summary of one log.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Record {
    /// The log's path as found.
    pub log: String,
    /// Its name: the shortest path suffix that tells it from the other logs.
    pub name: String,
    /// How its fit ended.
    pub status: Status,
    /// The error of a failed log.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Pole pairs used (given or chosen).
    pub pole_pairs: Option<u32>,
    /// The voltage hold of the reported fit (`dq` or `stator`; `steady` for the steady-state equations).
    pub hold: Option<String>,
    /// Whether the solver converged.
    pub converged: Option<bool>,
    /// Every parameter (nuisance ones included).
    pub parameters: Vec<Quantity>,
    /// Derived quantities: `k_t`, `psi_f`, and with `--t0` the temperatures.
    pub derived: Vec<Quantity>,
    /// Fit percentage of each output `(output, %)`: `100 (1 − ‖y − ŷ‖/‖y − ȳ‖)`.
    #[serde(deserialize_with = "nan_if_null_pairs")]
    pub fit_percent: Vec<(String, f64)>,
    /// The fit's warnings.
    pub warnings: Vec<WarningRecord>,
    /// Read and fit time of this log \[s\] (on a core shared with the other logs).
    pub time_s: Option<f64>,
}

impl Record {
    /// The record of the log at `path` named `name` from its fit or its error.
    pub fn new(path: &Path, name: &str, result: crate::Result<PmsmFit>) -> Self {
        let base = |status, error| Record {
            log: path.display().to_string(),
            name: name.to_string(),
            status,
            error,
            pole_pairs: None,
            hold: None,
            converged: None,
            parameters: Vec::new(),
            derived: Vec::new(),
            fit_percent: Vec::new(),
            warnings: Vec::new(),
            time_s: None,
        };
        let fit = match result {
            Ok(fit) => fit,
            Err(e) => return base(Status::Failed, Some(e.to_string())),
        };
        let status = if fit.trusted() { Status::Ok } else { Status::Untrusted };
        let parameters = fit
            .parameters
            .iter()
            .map(|p| Quantity {
                name: p.name.clone(),
                unit: p.unit.clone(),
                value: p.value,
                std_error: p.std_error,
                ci95: p.ci95,
                fixed: p.fixed,
            })
            .collect();
        let tq = crate::estimate::t_quantile_975(fit.uncertainty.dof);
        let derived = fit
            .derived
            .iter()
            .map(|d| Quantity {
                name: d.name.clone(),
                unit: d.unit.clone(),
                value: d.value,
                std_error: d.std_error,
                ci95: d.interval(tq),
                fixed: false,
            })
            .collect();
        let stats = &fit.fit;
        Record {
            pole_pairs: Some(fit.pole_pairs),
            // The steady-state equations have no hold: the column names the model instead.
            hold: Some(if fit.steady_state() { "steady".into() } else { fit.hold.to_string() }),
            converged: Some(fit.solver.success),
            parameters,
            derived,
            fit_percent: stats.outputs.iter().cloned().zip(stats.fit_percent.iter().copied()).collect(),
            warnings: fit
                .warnings
                .iter()
                .map(|w| WarningRecord {
                    code: w.code.clone(),
                    message: w.message.clone(),
                    untrusted: w.untrusted,
                })
                .collect(),
            time_s: Some(fit.timing.total_s),
            ..base(status, None)
        }
    }
}

/// Names (and units) of a list of quantities over all records, in first-seen order.
fn quantities<'a>(
    records: &'a [Record],
    list: impl Fn(&'a Record) -> &'a [Quantity],
) -> Vec<(&'a str, &'a str)> {
    let mut out: Vec<(&str, &str)> = Vec::new();
    for q in records.iter().flat_map(|r| list(r).iter()) {
        if !out.iter().any(|(n, _)| *n == q.name) {
            out.push((&q.name, &q.unit));
        }
    }
    out
}

/// One cell of the summary.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    /// Text (path, name, status, error, hold, warnings).
    Text(String),
    /// A count (pole pairs).
    Count(u32),
    /// A yes/no (converged).
    Flag(bool),
    /// A number in SI units, `None` when not finite (written `{:e}`, or empty).
    Number(Option<f64>),
    /// A time \[s\] (written with 3 decimals).
    Seconds(f64),
    /// No value for this log (an empty cell).
    Missing,
}

/// The summary's columns, `(header, one cell per record)`: `log, name, status, error,
/// pole_pairs, hold, converged`, then for each parameter and derived quantity `NAME [unit]`,
/// `NAME_se [unit]` and the ends of its 95 % interval `NAME_low [unit]`, `NAME_high [unit]`
/// ([`Quantity::ci95`]: the report's interval, asymmetric where the fit's is, e.g. a
/// restricted IV interval; SI units, no prefix; the standard error and interval of a fixed
/// parameter missing), `fit_OUTPUT [%]`, `warnings` (`code: message`, `; ` between them),
/// `time [s]`.
pub fn columns(records: &[Record]) -> Vec<(String, Vec<Cell>)> {
    let params = quantities(records, |r| &r.parameters);
    let derived = quantities(records, |r| &r.derived);
    let mut outputs: Vec<&str> = Vec::new();
    for (o, _) in records.iter().flat_map(|r| &r.fit_percent) {
        if !outputs.contains(&o.as_str()) {
            outputs.push(o);
        }
    }
    let text = |s: &Option<String>| s.clone().map_or(Cell::Missing, Cell::Text);
    let mut out: Vec<(String, Vec<Cell>)> = vec![
        ("log".into(), records.iter().map(|r| Cell::Text(r.log.clone())).collect()),
        ("name".into(), records.iter().map(|r| Cell::Text(r.name.clone())).collect()),
        ("status".into(), records.iter().map(|r| Cell::Text(r.status.word().into())).collect()),
        ("error".into(), records.iter().map(|r| text(&r.error)).collect()),
        (
            "pole_pairs".into(),
            records.iter().map(|r| r.pole_pairs.map_or(Cell::Missing, Cell::Count)).collect(),
        ),
        ("hold".into(), records.iter().map(|r| text(&r.hold)).collect()),
        ("converged".into(), records.iter().map(|r| r.converged.map_or(Cell::Missing, Cell::Flag)).collect()),
    ];
    let num = |v: f64| Cell::Number(v.is_finite().then_some(v));
    for (derived_list, names) in [(false, &params), (true, &derived)] {
        for (n, u) in names.iter() {
            let u = display_unit(u).0;
            let q = |r: &Record| {
                let list = if derived_list { &r.derived } else { &r.parameters };
                list.iter().find(|q| q.name == *n).cloned()
            };
            out.push((
                format!("{n} [{u}]"),
                records.iter().map(|r| q(r).map_or(Cell::Missing, |q| num(q.value))).collect(),
            ));
            let se = |q: Quantity| if q.fixed { Cell::Missing } else { num(q.std_error) };
            out.push((
                format!("{n}_se [{u}]"),
                records.iter().map(|r| q(r).map_or(Cell::Missing, se)).collect(),
            ));
            for (end, side) in [(0, "low"), (1, "high")] {
                let ci = |q: Quantity| if q.fixed { Cell::Missing } else { num(q.ci95[end]) };
                out.push((
                    format!("{n}_{side} [{u}]"),
                    records.iter().map(|r| q(r).map_or(Cell::Missing, ci)).collect(),
                ));
            }
        }
    }
    for o in &outputs {
        let f =
            |r: &Record| r.fit_percent.iter().find(|(n, _)| n == o).map_or(Cell::Missing, |(_, f)| num(*f));
        out.push((format!("fit_{o} [%]"), records.iter().map(f).collect()));
    }
    let warnings = |r: &Record| {
        let w: Vec<String> = r.warnings.iter().map(|w| format!("{}: {}", w.code, w.message)).collect();
        Cell::Text(w.join("; "))
    };
    out.push(("warnings".into(), records.iter().map(warnings).collect()));
    out.push((
        "time [s]".into(),
        records.iter().map(|r| r.time_s.map_or(Cell::Missing, Cell::Seconds)).collect(),
    ));
    out
}

/// The summary as CSV: the [`columns`], a row per log; cells a log has no value for are
/// empty.
///
/// # Errors
/// [`crate::Error::Write`] if the CSV writer fails (it writes to memory).
pub fn csv(records: &[Record]) -> crate::Result<String> {
    let columns = columns(records);
    let mut w = csv::Writer::from_writer(Vec::new());
    let err = |e: csv::Error| crate::Error::Write { path: "summary CSV".into(), source: e.into() };
    w.write_record(columns.iter().map(|(h, _)| h)).map_err(err)?;
    for k in 0..records.len() {
        let row = columns.iter().map(|(_, cells)| match &cells[k] {
            Cell::Text(s) => s.clone(),
            Cell::Count(n) => n.to_string(),
            Cell::Flag(b) => b.to_string(),
            Cell::Number(Some(v)) => format!("{v:e}"),
            Cell::Seconds(t) => format!("{t:.3}"),
            Cell::Number(None) | Cell::Missing => String::new(),
        });
        w.write_record(row).map_err(err)?;
    }
    let bytes = w.into_inner().map_err(|e| err(e.into_error().into()))?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

/// The summary as JSON: the pattern, the counts, the wall time \[s\] and the records.
pub fn json(pattern: &str, records: &[Record], wall_s: f64) -> String {
    let count = |s: Status| records.iter().filter(|r| r.status == s).count();
    let v = serde_json::json!({
        "each": pattern,
        "ok": count(Status::Ok),
        "untrusted": count(Status::Untrusted),
        "failed": count(Status::Failed),
        "wall_s": wall_s,
        "logs": records,
    });
    serde_json::to_string_pretty(&v).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
}

/// The table printed on stdout: one row per log with its name, status, the free
/// parameters (each column in one SI-prefixed unit), the lowest fit % and the hold;
/// failed logs with their error below.
pub fn table(records: &[Record]) -> String {
    let params: Vec<(&str, &str)> = quantities(records, |r| &r.parameters)
        .into_iter()
        .filter(|(n, _)| records.iter().flat_map(|r| &r.parameters).any(|q| q.name == *n && !q.fixed))
        .collect();
    let scales: Vec<UnitScale> = params
        .iter()
        .map(|(n, u)| {
            // One prefix per column, from the largest estimate.
            let v = records.iter().flat_map(|r| &r.parameters).filter(|q| q.name == *n);
            UnitScale::for_value(v.map(|q| q.value.abs()).fold(0.0, f64::max), u)
        })
        .collect();
    let mut head: Vec<String> = vec!["log".into(), "status".into()];
    head.extend(params.iter().zip(&scales).map(|((n, _), s)| format!("{n} [{}]", s.symbol)));
    head.extend(["fit % (min)".to_string(), "hold".to_string()]);
    let mut rows = vec![head];
    for r in records {
        let mut row = vec![r.name.clone(), r.status.word().to_string()];
        for ((n, _), s) in params.iter().zip(&scales) {
            let q = r.parameters.iter().find(|q| q.name == *n);
            row.push(
                q.map(|q| s.number(q.value, decimals_for(q.value / s.factor, 6)))
                    .unwrap_or_else(|| "-".into()),
            );
        }
        let fit = r.fit_percent.iter().map(|(_, f)| *f).fold(f64::INFINITY, f64::min);
        row.push(if fit.is_finite() { format!("{fit:.3}") } else { "-".into() });
        row.push(r.hold.clone().unwrap_or_else(|| "-".into()));
        rows.push(row);
    }
    let widths: Vec<usize> =
        (0..rows[0].len()).map(|c| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0)).collect();
    let mut out = String::new();
    for (i, row) in rows.iter().enumerate() {
        let cells: Vec<String> = row
            .iter()
            .zip(&widths)
            .enumerate()
            .map(|(c, (s, w))| if c < 2 { format!("{s:<w$}") } else { format!("{s:>w$}") })
            .collect();
        out.push_str(cells.join("  ").trim_end());
        out.push('\n');
        if i == 0 {
            out.push_str(&"-".repeat(widths.iter().sum::<usize>() + 2 * (widths.len() - 1)));
            out.push('\n');
        }
    }
    for r in records.iter().filter(|r| r.status == Status::Failed) {
        out.push_str(&format!("{}: {}\n", r.name, r.error.as_deref().unwrap_or("")));
    }
    out
}
