//! The trend plot: quantities estimated on a sequence of runs (e.g. one fit per log), each
//! on its own panel over the run index, with its 95 % interval as an error bar.

use super::draw::{Drawn, FONT, Key, PANEL, TITLE, WIDTH, color, range, tick, under_header};
use super::plot_error;
use crate::error::{Error, Result};
use plotters::prelude::*;

/// At most this many runs are named on the x axis; with more, the axis shows run numbers.
pub const MAX_NAMED_RUNS: usize = 8;

/// One estimate of a quantity on one run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrendPoint {
    /// The estimate \[the series' unit\].
    pub value: f64,
    /// Its 95 % interval `[lower, upper]` \[the series' unit\], when known.
    pub interval: Option<[f64; 2]>,
    /// Drawn hollow and counted in the legend as [`Trend::flag`] (e.g. an untrusted fit).
    pub flagged: bool,
}

/// A quantity over the runs: its name, unit, and one point per run (`None` where the run
/// has no estimate, e.g. a failed fit: a gap).
#[derive(Clone, Debug, PartialEq)]
pub struct TrendSeries {
    /// Name on the panel and axis, e.g. `r_s`.
    pub name: String,
    /// Unit of the values, e.g. `mΩ`.
    pub unit: String,
    /// One entry per run, in the order of [`Trend::runs`].
    pub points: Vec<Option<TrendPoint>>,
}

/// What the trend plot shows: a title, the runs in order, the series, and what a flagged
/// point means.
#[derive(Clone, Copy, Debug)]
pub struct Trend<'a> {
    /// Title line, e.g. `Parameters of 12 logs fitted separately`.
    pub title: &'a str,
    /// Second line under the title (what the x axis orders by, counts).
    pub subtitle: &'a str,
    /// Name of each run, in order; shown as tick labels when at most
    /// [`MAX_NAMED_RUNS`], else the runs are numbered from 1.
    pub runs: &'a [String],
    /// What the x axis orders by, e.g. `log (file-name order)`.
    pub x_desc: &'a str,
    /// Legend text of a flagged point, e.g. `untrusted fit`.
    pub flag: &'a str,
    /// The panels, top to bottom.
    pub series: &'a [TrendSeries],
}

/// The trend plot as SVG text: one panel per series, the estimates as points over the run
/// index (x = 1, 2, … in the order of `trend.runs`) with their 95 % intervals as error
/// bars; flagged points hollow; a run without a point leaves a gap. Intervals reaching
/// beyond the axis (the axis spans the estimates and the intervals of unflagged points)
/// are cut at its edge, which the panel's caption says.
///
/// # Errors
/// [`Error::InvalidOption`] (option `plot`) for no run, no series, a series whose point
/// count differs from the run count, or a drawing failure.
pub fn trend_svg(trend: &Trend<'_>) -> Result<String> {
    let bad = |reason: String| Error::InvalidOption { option: "plot".into(), reason };
    let n = trend.runs.len();
    if n == 0 || trend.series.is_empty() {
        return Err(bad("nothing to plot: no run or no quantity".into()));
    }
    if let Some(s) = trend.series.iter().find(|s| s.points.len() != n) {
        return Err(bad(format!("`{}` has {} points for {n} runs", s.name, s.points.len())));
    }
    let height = TITLE + trend.series.len() as u32 * PANEL;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
        let drawn: Drawn = (|| {
            root.fill(&WHITE)?;
            let (head, body) = root.split_vertically(TITLE);
            head.draw_text(trend.title, &(FONT, 20).into_font().color(&BLACK), (16, 10))?;
            head.draw_text(trend.subtitle, &(FONT, 15).into_font().color(&RGBColor(70, 70, 70)), (16, 38))?;
            for (i, (area, s)) in
                body.split_evenly((trend.series.len(), 1)).iter().zip(trend.series).enumerate()
            {
                panel(area, trend, s, color(i))?;
            }
            root.present()?;
            Ok(())
        })();
        drawn.map_err(plot_error)?;
    }
    Ok(svg)
}

/// The tick label of run `k` (0-based): its name when few runs are named, else `k + 1`.
fn run_label(trend: &Trend<'_>, k: usize, max_chars: usize) -> String {
    if trend.runs.len() > MAX_NAMED_RUNS {
        return (k + 1).to_string();
    }
    let name = &trend.runs[k];
    if name.chars().count() <= max_chars {
        return name.clone();
    }
    let keep: String = name.chars().take(max_chars.saturating_sub(1)).collect();
    format!("{keep}…")
}

/// One series on `area`: header (caption, legend), axes, points and error bars.
fn panel(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    trend: &Trend<'_>,
    s: &TrendSeries,
    c: RGBColor,
) -> Drawn {
    let n = trend.runs.len();
    let points: Vec<(usize, TrendPoint)> =
        s.points.iter().enumerate().filter_map(|(k, p)| p.map(|p| (k, p))).collect();
    let y = range(points.iter().flat_map(|(_, p)| {
        let bar = p.interval.filter(|_| !p.flagged).unwrap_or([p.value, p.value]);
        [p.value, bar[0], bar[1]]
    }));
    // A span below 10⁻⁹ of the values is rounding noise that no tick label can show:
    // widen it to that.
    let mid = 0.5 * (y.start + y.end);
    let floor = 1e-9 * mid.abs();
    let y = if y.end - y.start < floor { mid - floor / 2.0..mid + floor / 2.0 } else { y };
    let clipped = points.iter().any(|(_, p)| {
        p.interval.is_some_and(|[lo, hi]| lo < y.start || hi > y.end || !lo.is_finite() || !hi.is_finite())
    });
    let caption = format!(
        "{} [{}]{}",
        s.name,
        s.unit,
        if clipped { " (intervals beyond the axis cut at its edge)" } else { "" }
    );
    let mut keys = vec![
        ("estimate".to_string(), Key::Dot(c.filled())),
        ("95 % interval".to_string(), Key::Line(c.stroke_width(2))),
    ];
    if points.iter().any(|(_, p)| p.flagged) {
        keys.push((trend.flag.to_string(), Key::Dot(c.stroke_width(2))));
    }
    if points.is_empty() {
        keys.clear();
    }
    // Room per run for a name at 6.5 px a character at 13 px.
    let slot = (WIDTH - 120) as usize / n;
    let max_chars = (slot / 7).max(4);
    let y_span = y.end - y.start;
    // Run k (0-based) at x = k + 1; at most n ticks, so that plotters steps by whole runs.
    let x = 0.5..n as f64 + 0.5;
    let mut chart = under_header(area, &caption, &keys)?
        .margin_bottom(4)
        .y_label_area_size(112)
        .build_cartesian_2d(x, y.clone())?;
    let x_fmt = |v: &f64| {
        let k = v.round();
        if (v - k).abs() < 1e-6 && k >= 1.0 && (k as usize) <= n {
            run_label(trend, k as usize - 1, max_chars)
        } else {
            String::new()
        }
    };
    let y_fmt = |v: &f64| fine_tick(*v, y_span);
    let x_desc = if n > MAX_NAMED_RUNS {
        format!("{} — run number", trend.x_desc)
    } else {
        trend.x_desc.to_string()
    };
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(format!("{} [{}]", s.name, s.unit))
        .axis_desc_style((FONT, 15))
        .label_style((FONT, 13))
        .x_labels(n.min(if n > MAX_NAMED_RUNS { 20 } else { MAX_NAMED_RUNS }))
        .y_labels(6)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .disable_x_mesh()
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .draw()?;
    if points.is_empty() {
        let (w, h) = area.dim_in_pixel();
        let grey = (FONT, 14).into_font().color(&RGBColor(110, 110, 110));
        area.draw_text("no estimate on any run", &grey, (w as i32 / 3, h as i32 / 2))?;
        return Ok(());
    }
    let cut = |v: f64| if v.is_nan() { v } else { v.clamp(y.start, y.end) };
    let width = ((slot / 4).clamp(2, 12)) as u32;
    chart.draw_series(points.iter().filter_map(|(k, p)| {
        let [lo, hi] = p.interval?;
        let (lo, hi) = (cut(lo), cut(hi));
        (lo.is_finite() && hi.is_finite())
            .then(|| ErrorBar::new_vertical((*k + 1) as f64, lo, cut(p.value), hi, c.stroke_width(2), width))
    }))?;
    let radius = if n > 40 { 3 } else { 5 };
    chart.draw_series(points.iter().map(|(k, p)| {
        let style = if p.flagged { WHITE.filled() } else { c.filled() };
        Circle::new(((*k + 1) as f64, cut(p.value)), radius, style)
    }))?;
    chart.draw_series(
        points
            .iter()
            .filter(|(_, p)| p.flagged)
            .map(|(k, p)| Circle::new(((*k + 1) as f64, cut(p.value)), radius, c.stroke_width(2))),
    )?;
    Ok(())
}

/// A tick label on an axis spanning `span` with the digits that tell its ticks apart
/// (estimates of one quantity on several runs may differ in the 7th digit): the
/// decimals of a sixth of the span (about plotters' tick step), trailing zeros dropped;
/// exponent form outside [1e-3, 1e5).
fn fine_tick(v: f64, span: f64) -> String {
    let a = v.abs();
    if v == 0.0 || span.is_nan() || span <= 0.0 || !(1e-3..1e5).contains(&a) {
        return tick(v, span);
    }
    let decimals = (-(span / 6.0).log10().floor() as i32).clamp(0, 12) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(n: usize) -> TrendSeries {
        let points = (0..n)
            .map(|k| {
                (k != 1).then_some(TrendPoint {
                    value: 1.0 + 0.01 * k as f64,
                    interval: Some([0.99 + 0.01 * k as f64, 1.01 + 0.01 * k as f64]),
                    flagged: k == 2,
                })
            })
            .collect();
        TrendSeries { name: "a".into(), unit: "V".into(), points }
    }

    #[test]
    fn names_few_runs_numbers_many() {
        for (n, named) in [(3, true), (50, false)] {
            let runs: Vec<String> = (0..n).map(|k| format!("run_{k:02}")).collect();
            let s = [series(n)];
            let t = Trend {
                title: "T",
                subtitle: "S",
                runs: &runs,
                x_desc: "log",
                flag: "untrusted",
                series: &s,
            };
            let svg = trend_svg(&t).unwrap();
            assert!(svg.starts_with("<svg") && svg.contains("a [V]") && svg.contains("untrusted"));
            assert_eq!(svg.contains("\nrun_00\n"), named, "{n} runs");
            assert_eq!(svg.contains("run number"), !named);
        }
    }

    #[test]
    fn ticks_tell_close_values_apart() {
        assert_eq!(fine_tick(900.0055, 0.004), "900.0055");
        assert_ne!(fine_tick(900.0055, 0.004), fine_tick(900.0062, 0.004));
        assert_eq!(fine_tick(4.5, 3.0), "4.5");
        assert_eq!(fine_tick(538.887715, 2e-5), "538.887715");
    }

    #[test]
    fn rounding_noise_is_not_drawn_as_a_trend() {
        let p = |v: f64| Some(TrendPoint { value: v, interval: None, flagged: false });
        let s = [TrendSeries {
            name: "l".into(),
            unit: "mH".into(),
            points: vec![p(4.5), p(4.5 * (1.0 + 1e-15))],
        }];
        let runs = vec!["a".to_string(), "b".to_string()];
        let t = Trend { title: "T", subtitle: "S", runs: &runs, x_desc: "log", flag: "f", series: &s };
        let svg = trend_svg(&t).unwrap();
        // The axis spans 10⁻⁹ of the value: ticks 4.499999999 … 4.500000001, told apart.
        assert!(svg.contains("\n4.500000001\n") || svg.contains("\n4.499999999\n"), "{svg}");
    }

    #[test]
    fn refuses_mismatched_series() {
        let runs = vec!["a".to_string(), "b".to_string()];
        let s = [series(3)];
        let t = Trend { title: "T", subtitle: "S", runs: &runs, x_desc: "log", flag: "f", series: &s };
        assert!(trend_svg(&t).unwrap_err().to_string().contains("3 points for 2 runs"));
        let t = Trend { runs: &[], ..t };
        assert!(trend_svg(&t).is_err());
    }
}
