//! The report of `greybox design`: its JSON structure, the printed table and the plot.

use crate::drive::DriveConfig;
use crate::drive::Knobs;
use crate::drive::PlanPrediction;
use crate::estimate::design::{Criterion, Target};
use crate::report::eng::format_eng;
use crate::report::plot::{Trend, TrendPoint, TrendSeries, trend_svg};
use serde::{Deserialize, Serialize};

/// The report of `greybox design` (`--json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DesignReport {
    /// The ranking criterion.
    pub criterion: Criterion,
    /// Where the noise came from: `flags`, `plans` (their `sensors`) or the report's
    /// residuals (`params`).
    pub noise_source: String,
    /// Every plan's prediction, in the order given (scenarios, then files).
    pub plans: Vec<PlanPrediction>,
    /// Plan names, best first by `criterion`.
    pub ranking: Vec<String>,
    /// The knob search, with `--search`.
    pub search: Option<SearchReport>,
}

/// The knob search of `greybox design --search`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchReport {
    /// The targets.
    pub targets: Vec<Target>,
    /// Every candidate evaluated, shortest first: name, knobs, achieved half-widths or why
    /// it was rejected.
    pub candidates: Vec<SearchedCandidate>,
    /// The shortest candidate reaching every target, with its prediction.
    pub best: Option<PlanPrediction>,
}

/// One evaluated candidate of the search.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchedCandidate {
    /// Name: base plan and knobs.
    pub name: String,
    /// The knobs.
    pub knobs: Knobs,
    /// Achieved relative 95 % half-width per target \[-\].
    pub achieved: Vec<f64>,
    /// Why it was rejected (a limit it reaches), if it was.
    pub rejected: Option<String>,
    /// Whether it reaches every target.
    pub reaches: bool,
}

/// The table of every plan, the ranking and the search, as printed.
pub(super) fn text(r: &DesignReport, plans: &[DriveConfig]) -> String {
    let mut s = String::new();
    for (p, cfg) in r.plans.iter().zip(plans) {
        let q = &p.prediction;
        s += &format!(
            "{}: {} s ({} samples), phase-current noise {} (pole {:.3}); limits used: current {:.0} %, voltage {:.0} %{}\n",
            p.plan,
            p.duration,
            q.samples,
            format_eng(p.current_noise, "A", 4),
            p.current_noise_pole,
            100.0 * p.limits.current,
            100.0 * p.limits.voltage,
            p.limits
                .reached()
                .map_or(String::new(), |l| format!(" ({l}: the run would not follow its references)"))
        );
        s += &format!(
            "  {:<6} {:>18} {:>16} {:>44} {:>10}\n",
            "param", "nominal", "se", "95 % interval", "index [%]"
        );
        for x in &q.parameters {
            s += &format!(
                "  {:<6} {:>18} {:>16} {:>44} {:>10.4}\n",
                x.name,
                format_eng(x.value, &x.unit, 5),
                format_eng(x.std_error, &x.unit, 4),
                format!("[{}, {}]", format_eng(x.ci95[0], &x.unit, 7), format_eng(x.ci95[1], &x.unit, 7)),
                x.error_index_percent
            );
        }
        // The most correlated pair (the full matrix is in the JSON).
        let n = q.parameters.len();
        let pair = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .max_by(|&(a, b), &(c, d)| q.correlation[a][b].abs().total_cmp(&q.correlation[c][d].abs()));
        let corr = pair.map_or(String::new(), |(i, j)| {
            format!(
                "; largest correlation {}-{} {:+.3}",
                q.parameters[i].name, q.parameters[j].name, q.correlation[i][j]
            )
        });
        s += &format!(
            "  condition number {:.1}; D {:.3}, A {:.4e}, E {:.4e}{corr}\n",
            q.condition_number, q.d_criterion, q.a_criterion, q.e_criterion
        );
        if cfg.sensors.voltage_noise > 0.0 || cfg.sensors.speed_noise > 0.0 {
            s += "  note: the plan's voltage and speed noise are errors in variables, not in this bound\n";
        }
    }
    let name = format!("{:?}", r.criterion).to_lowercase();
    s += &format!("ranking ({name}-criterion, best first): {}\n", r.ranking.join(" > "));
    if let Some(search) = &r.search {
        let goal: Vec<String> =
            search.targets.iter().map(|t| format!("{} ±{} %", t.parameter, 100.0 * t.half_width)).collect();
        s += &format!(
            "search for {} (95 %): {} candidates evaluated\n",
            goal.join(", "),
            search.candidates.len()
        );
        for c in &search.candidates {
            let what = match &c.rejected {
                Some(reason) => format!("rejected: {reason}"),
                None => {
                    let a: Vec<String> = c.achieved.iter().map(|v| format!("±{:.3} %", 100.0 * v)).collect();
                    format!("{}{}", a.join(", "), if c.reaches { "  reaches" } else { "" })
                }
            };
            s += &format!("  {:<48} {what}\n", c.name);
        }
        s += &match &search.best {
            Some(b) => format!("shortest plan reaching the targets: {} ({} s)\n", b.plan, b.duration),
            None => {
                "no candidate reaches the targets: longer records, more injection or other plans\n".into()
            }
        };
    }
    s
}

/// The plot: per parameter a panel, per plan the predicted 95 % interval relative to the
/// nominal value \[%\].
pub(super) fn plot(r: &DesignReport) -> crate::Result<String> {
    let runs: Vec<String> = r.plans.iter().map(|p| p.plan.clone()).collect();
    let names: Vec<String> = r
        .plans
        .first()
        .map(|p| p.prediction.parameters.iter().map(|q| q.name.clone()).collect())
        .unwrap_or_default();
    let series: Vec<TrendSeries> = names
        .iter()
        .map(|n| TrendSeries {
            name: n.clone(),
            unit: "% of nominal".into(),
            points: r
                .plans
                .iter()
                .map(|p| {
                    p.prediction.parameter(n).map(|q| {
                        let half = 196.0 * q.std_error / q.value.abs();
                        TrendPoint { value: 0.0, interval: Some([-half, half]), flagged: false }
                    })
                })
                .collect(),
        })
        .collect();
    trend_svg(&Trend {
        title: "Predicted 95 % intervals of the planned experiments",
        subtitle: "relative to the nominal values (the point); Cramér–Rao bound of an output-error fit",
        runs: &runs,
        x_desc: "plan",
        flag: "",
        series: &series,
    })
}
