//! The batch's trend plot: the motor's parameters over the logs (file-name order), drawn
//! by the generic [`crate::report::plot::trend_svg`] with the units and labels chosen
//! here.

use crate::app::summary::{Record, Status};
use crate::report::eng::UnitScale;
use crate::report::plot::{Trend, TrendPoint, TrendSeries, trend_svg};

/// The trend plot of the records' parameters (every parameter some log estimated, fixed
/// ones and per-log nuisance parameters included when estimated), each in one SI-prefixed
/// unit, with its 95 % interval; untrusted fits hollow, failed logs as gaps. The x axis is
/// the file-name order: the logs carry no start time that could order them (their time
/// columns are relative).
///
/// # Errors
/// Those of [`trend_svg`] (a drawing failure; no log fitted leaves the panels empty).
pub fn svg(pattern: &str, records: &[Record]) -> crate::Result<String> {
    let mut names: Vec<(&str, &str)> = Vec::new();
    for q in records.iter().flat_map(|r| r.parameters.iter().filter(|q| !q.fixed)) {
        if !names.iter().any(|(n, _)| *n == q.name) {
            names.push((&q.name, &q.unit));
        }
    }
    let series: Vec<TrendSeries> = names
        .iter()
        .map(|(name, unit)| {
            let of = |r: &Record| r.parameters.iter().find(|q| q.name == *name && !q.fixed).cloned();
            let reference = records.iter().filter_map(of).map(|q| q.value.abs()).fold(0.0, f64::max);
            let scale = UnitScale::for_value(reference, unit);
            let points = records
                .iter()
                .map(|r| {
                    of(r).map(|q| TrendPoint {
                        value: q.value / scale.factor,
                        interval: Some([q.ci95[0] / scale.factor, q.ci95[1] / scale.factor])
                            .filter(|[lo, hi]| lo.is_finite() && hi.is_finite()),
                        flagged: r.status == Status::Untrusted,
                    })
                })
                .collect();
            TrendSeries { name: name.to_string(), unit: scale.symbol, points }
        })
        .collect();
    let count = |s: Status| records.iter().filter(|r| r.status == s).count();
    let title = format!("Parameters of {} logs fitted one by one ({pattern})", records.len());
    let subtitle = format!(
        "{} ok, {} untrusted (hollow), {} failed (gaps); bars: 95 % intervals; x: the logs in file-name order",
        count(Status::Ok),
        count(Status::Untrusted),
        count(Status::Failed)
    );
    let runs: Vec<String> = records.iter().map(|r| r.name.clone()).collect();
    let series = if series.is_empty() {
        vec![TrendSeries { name: "no parameter".into(), unit: "-".into(), points: vec![None; runs.len()] }]
    } else {
        series
    };
    trend_svg(&Trend {
        title: &title,
        subtitle: &subtitle,
        runs: &runs,
        x_desc: "log (file-name order)",
        flag: "untrusted fit",
        series: &series,
    })
}
