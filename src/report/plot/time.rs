//! The time panels of the fit and compare plots: the context signal, each output measured
//! against simulated, and each output's residual with its ±2σ band. Several logs are drawn
//! one after another on one time axis, separated by dashed lines.

use super::Context;
use super::decimate_min_max;
use super::draw::{Area, Chart, Drawn, Key, MEASURED, chart, color, dashed, range};
use crate::report::Comparison;
use plotters::prelude::*;

/// Logs laid out on one time axis: where each starts \[s\] and where the last ends.
pub(super) struct Timeline {
    /// Start of each log \[s\].
    pub starts: Vec<f64>,
    /// Start of the axis \[s\]: the log's own first time for one log, 0 for several.
    pub begin: f64,
    /// End of the last log \[s\].
    pub end: f64,
}

impl Timeline {
    /// The logs of `comparisons`, one after another.
    pub fn new(comparisons: &[Comparison]) -> Self {
        let mut starts = Vec::with_capacity(comparisons.len());
        // One log in its own time; several one after another from 0.
        let mut end = match comparisons {
            [c] => c.t0,
            _ => 0.0,
        };
        let begin = end;
        for c in comparisons {
            starts.push(end);
            end += c.len() as f64 * c.h;
        }
        Self { starts, begin, end }
    }
    /// The time axis label.
    pub fn label(&self) -> &'static str {
        if self.starts.len() > 1 { "t [s] (logs one after another)" } else { "t [s]" }
    }
    /// Time of every sample of log `i` \[s\].
    fn times(&self, comparisons: &[Comparison], i: usize) -> Vec<f64> {
        let c = &comparisons[i];
        (0..c.len()).map(|k| self.starts[i] + k as f64 * c.h).collect()
    }
}

/// Number of time panels: the context's, then two per output.
pub(super) fn count(comparisons: &[Comparison], context: Option<&Context<'_>>) -> usize {
    usize::from(context.is_some()) + 2 * comparisons.first().map_or(0, |c| c.outputs.len())
}

/// Draws the time panels on `areas` (at least [`count`] of them).
pub(super) fn draw(areas: &[Area<'_>], comparisons: &[Comparison], context: Option<&Context<'_>>) -> Drawn {
    let line = Timeline::new(comparisons);
    let mut next = areas.iter();
    let mut take = || next.next().ok_or("too few panels");
    let ny = comparisons.first().map_or(0, |c| c.outputs.len());
    let times: Vec<Vec<f64>> = (0..comparisons.len()).map(|i| line.times(comparisons, i)).collect();
    let x = line.begin..line.end;
    if let Some(ctx) = context {
        let y = range(ctx.per_log.iter().flat_map(|v| v.iter().copied()));
        let style = MEASURED.stroke_width(1);
        let keys = [(format!("{} measured", ctx.name), Key::Line(style.stroke_width(2)))];
        let caption = format!("{} (measured)", ctx.name);
        let mut ch = chart(take()?, &caption, &keys, x.clone(), y, line.label(), &axis(ctx.name, ctx.unit))?;
        for (i, (t, v)) in times.iter().zip(ctx.per_log).enumerate() {
            ch.draw_series(LineSeries::new(decimated(&ch, &line, t, v, comparisons, i), style))?;
        }
        separators(&mut ch, &line)?;
    }
    for o in 0..ny {
        let name = &comparisons[0].outputs[o];
        let unit = comparisons[0].unit(o);
        let measured: Vec<Vec<f64>> = comparisons.iter().map(|c| c.measured(o)).collect();
        let simulated: Vec<Vec<f64>> = comparisons.iter().map(|c| c.simulated(o)).collect();
        let y = range(measured.iter().chain(&simulated).flat_map(|v| v.iter().copied()));
        let styles = [MEASURED.stroke_width(1), color(0).stroke_width(1)];
        let predicted = match comparisons[0].horizon {
            Some(k) => format!("{k}-step prediction"),
            None => "simulated".to_string(),
        };
        let keys = [
            (format!("{name} measured"), Key::Line(styles[0].stroke_width(2))),
            (format!("{name} {predicted}"), Key::Line(styles[1].stroke_width(2))),
        ];
        let caption = format!("{name}: measured and {predicted}");
        let mut ch = chart(take()?, &caption, &keys, x.clone(), y, line.label(), &axis(name, unit))?;
        for (data, style) in [&measured, &simulated].into_iter().zip(styles) {
            for (i, (t, v)) in times.iter().zip(data).enumerate() {
                ch.draw_series(LineSeries::new(decimated(&ch, &line, t, v, comparisons, i), style))?;
            }
        }
        separators(&mut ch, &line)?;
        // The residual of the output at the samples the fit counted, with ±2σ (σ: their RMS
        // residual over all logs, the report's figure); samples weighted out are not drawn.
        let residual: Vec<Vec<f64>> = comparisons
            .iter()
            .zip(measured.iter().zip(&simulated))
            .map(|(c, (m, s))| (0..m.len()).filter(|&k| c.counts(k)).map(|k| m[k] - s[k]).collect())
            .collect();
        let n: usize = residual.iter().map(Vec::len).sum();
        let sigma = (residual.iter().flatten().map(|e| e * e).sum::<f64>() / n.max(1) as f64).sqrt();
        let y = range(residual.iter().flatten().copied().chain([-2.5 * sigma, 2.5 * sigma]));
        let band = color(0).mix(0.12).filled();
        let style = color(3).stroke_width(1);
        let keys = [
            (format!("ε {name}"), Key::Line(style.stroke_width(2))),
            (format!("±2σ, σ = {}", crate::report::eng::format_eng(sigma, unit, 5)), Key::Band(band)),
        ];
        let masked = if comparisons.iter().any(|c| !c.counted.is_empty()) {
            ", weighted-out samples not drawn"
        } else {
            ""
        };
        let caption = format!("{name} residual (measured − {predicted}{masked})");
        let y_desc = axis(&format!("ε {name}"), unit);
        let mut ch = chart(take()?, &caption, &keys, x.clone(), y, line.label(), &y_desc)?;
        ch.draw_series(std::iter::once(Rectangle::new(
            [(line.begin, -2.0 * sigma), (line.end, 2.0 * sigma)],
            band,
        )))?;
        // Each run of counted samples its own line: a line across a weighted-out period
        // would look like data.
        let width = ch.plotting_area().dim_in_pixel().0 as f64;
        let span = (line.end - line.begin).max(f64::MIN_POSITIVE);
        for (i, c) in comparisons.iter().enumerate() {
            let (m, p) = (&measured[i], &simulated[i]);
            for run in counted_runs(c) {
                let t = &times[i][run.clone()];
                let e: Vec<f64> = run.clone().map(|k| m[k] - p[k]).collect();
                let columns = (width * run.len() as f64 * c.h / span).ceil().max(1.0) as usize;
                ch.draw_series(LineSeries::new(decimate_min_max(t, &e, columns), style))?;
            }
        }
        for y in [-2.0 * sigma, 2.0 * sigma] {
            dashed(&mut ch, &x, y, color(0).stroke_width(1), None)?;
        }
        separators(&mut ch, &line)?;
    }
    Ok(())
}

/// The runs of consecutive samples of `c` that its fit counted (all of them, one run, when
/// every sample counts).
fn counted_runs(c: &Comparison) -> Vec<std::ops::Range<usize>> {
    let mut runs = Vec::new();
    let mut start = None;
    for k in 0..=c.len() {
        match (k < c.len() && c.counts(k), start) {
            (true, None) => start = Some(k),
            (false, Some(s)) => {
                runs.push(s..k);
                start = None;
            }
            _ => {}
        }
    }
    runs
}

/// `name [unit]`, or the name alone without a unit.
pub(super) fn axis(name: &str, unit: &str) -> String {
    if unit.is_empty() { name.to_string() } else { format!("{name} [{unit}]") }
}

/// Log `i`'s samples decimated to its share of the chart's pixel columns.
fn decimated(
    ch: &Chart<'_, '_>,
    line: &Timeline,
    t: &[f64],
    v: &[f64],
    comparisons: &[Comparison],
    i: usize,
) -> Vec<(f64, f64)> {
    let width = ch.plotting_area().dim_in_pixel().0 as f64;
    let share =
        comparisons[i].len() as f64 * comparisons[i].h / (line.end - line.begin).max(f64::MIN_POSITIVE);
    decimate_min_max(t, v, (width * share).ceil().max(1.0) as usize)
}

/// Dashed vertical lines where one log ends and the next begins.
fn separators(ch: &mut Chart<'_, '_>, line: &Timeline) -> Drawn {
    let y = ch.y_range();
    for &t in line.starts.iter().skip(1) {
        let style = RGBColor(120, 120, 120).stroke_width(1);
        ch.draw_series(DashedLineSeries::new(vec![(t, y.start), (t, y.end)], 4, 4, style))?;
    }
    Ok(())
}
