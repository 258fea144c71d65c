//! The fit plot and the compare plot: time panels on the left ([`super::time`]); on the
//! right the parameter trace, the residual autocorrelation and the estimates with their
//! 95 % intervals (fit), or the autocorrelation and the metrics per log (compare).

use super::draw::{
    Area, Drawn, FONT, Key, PANEL, TITLE, WIDTH, chart, color, dashed, empty, legend, mark, range, value,
};
use super::{Context, plot_error, time};
use crate::error::{Error, Result};
use crate::estimate::FitResult;
use crate::estimate::WHITENESS_LAGS;
use crate::estimate::metrics::{self, Whiteness};
use crate::report::Comparison;
use crate::report::eng::format_eng;
use plotters::prelude::*;

/// The fit plot as SVG text: for each output measured against simulated over time and the
/// residual with its ±2σ band (σ the RMS residual), the `context` signal above them (e.g.
/// the speed), the parameter trace over the solver's iterations (`θ/θ̂ − 1`, the relative
/// deviation from the estimate), the residual autocorrelation with its 95 % whiteness bound (from
/// `fit.fit.whiteness`, else from the comparisons), and the free parameters' estimates with
/// their 95 % intervals. `comparisons` are the fit's logs simulated at the estimate (e.g.
/// e.g. a motor fit's `comparisons`), drawn one after another.
///
/// # Errors
/// [`Error::InvalidOption`] (option `plot`) for no comparison, comparisons with different
/// outputs, a context signal whose length differs from its log's, or a drawing failure.
pub fn fit_svg(fit: &FitResult, comparisons: &[Comparison], context: Option<&Context<'_>>) -> Result<String> {
    check(comparisons, context)?;
    let free: Vec<&crate::estimate::ParameterEstimate> = fit.parameters.iter().filter(|p| !p.fixed).collect();
    let left = time::count(comparisons, context).max(1);
    let estimates_h = PANEL.max(70 + 44 * free.len() as u32);
    let height = TITLE + (left as u32 * PANEL).max(2 * PANEL + estimates_h);
    let whiteness =
        if fit.fit.whiteness.is_empty() { pooled(comparisons) } else { fit.fit.whiteness.clone() };
    let fits: Vec<String> = fit
        .fit
        .outputs
        .iter()
        .zip(&fit.fit.fit_percent)
        .zip(&fit.fit.rms_residual)
        .enumerate()
        .map(|(i, ((o, f), r))| {
            format!("{o} {f:.2} % (rms residual {})", format_eng(*r, comparisons[0].unit(i), 5))
        })
        .collect();
    let title = [
        format!("Fit of {} to {}: {}", fit.model, list(&fit.experiments), fit.solver.termination),
        format!("fit: {}; N = {} samples per output", fits.join(", "), fit.fit.samples),
    ];
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
        let drawn: Drawn = (|| {
            let (left_area, right_area) = layout(&root, &title, left)?;
            time::draw(&left_area, comparisons, context)?;
            let (trace_area, rest) = right_area.split_vertically(PANEL);
            let (acf_area, est_area) = rest.split_vertically(PANEL);
            trace(&trace_area, fit, &free)?;
            autocorrelation(&acf_area, &comparisons[0].outputs, &whiteness)?;
            estimates(&est_area, &free)?;
            root.present()?;
            Ok(())
        })();
        drawn.map_err(plot_error)?;
    }
    Ok(svg)
}

/// The compare plot as SVG text: the time panels of [`fit_svg`] for a model simulated on
/// logs it was not fitted on, the residual autocorrelation pooled over the logs with its
/// 95 % bound, and the fit percentage and RMS residual of each log.
///
/// # Errors
/// As [`fit_svg`].
pub fn compare_svg(comparisons: &[Comparison], context: Option<&Context<'_>>) -> Result<String> {
    check(comparisons, context)?;
    let left = time::count(comparisons, context).max(1);
    let height = TITLE + (left as u32).max(2) * PANEL;
    let names: Vec<String> = comparisons.iter().map(|c| c.experiment.clone()).collect();
    let title = [
        format!("Validation: the model simulated on {} (not fitted on)", list(&names)),
        "measured against simulated outputs from the measured first state".to_string(),
    ];
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
        let drawn: Drawn = (|| {
            let (left_area, right_area) = layout(&root, &title, left)?;
            time::draw(&left_area, comparisons, context)?;
            let (acf_area, table_area) = right_area.split_vertically(PANEL);
            autocorrelation(&acf_area, &comparisons[0].outputs, &pooled(comparisons))?;
            table(&table_area, comparisons)?;
            root.present()?;
            Ok(())
        })();
        drawn.map_err(plot_error)?;
    }
    Ok(svg)
}

/// Checks what the plots draw before anything is drawn.
fn check(comparisons: &[Comparison], context: Option<&Context<'_>>) -> Result<()> {
    let bad = |reason: String| Error::InvalidOption { option: "plot".into(), reason };
    let Some(first) = comparisons.first() else { return Err(bad("nothing to plot: no log".into())) };
    if let Some(c) = comparisons.iter().find(|c| c.outputs != first.outputs || c.is_empty()) {
        return Err(bad(format!(
            "log `{}` has no samples or other outputs than `{}`",
            c.experiment, first.experiment
        )));
    }
    if let Some(ctx) = context {
        let lens_ok = ctx.per_log.len() == comparisons.len()
            && ctx.per_log.iter().zip(comparisons).all(|(v, c)| v.len() == c.len());
        if !lens_ok {
            return Err(bad(format!(
                "the signal `{}` does not have one value per sample of each log",
                ctx.name
            )));
        }
    }
    Ok(())
}

/// White background, the two title lines, and the left (62 %) and right columns below,
/// the left split evenly into `left` panels.
fn layout<'a>(root: &Area<'a>, title: &[String; 2], left: usize) -> Drawn<(Vec<Area<'a>>, Area<'a>)> {
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE);
    head.draw_text(&title[0], &(FONT, 20).into_font().color(&BLACK), (16, 10))?;
    head.draw_text(&title[1], &(FONT, 15).into_font().color(&RGBColor(70, 70, 70)), (16, 38))?;
    let (l, r) = body.split_horizontally(WIDTH * 62 / 100);
    let l = l.split_vertically(left as u32 * PANEL).0;
    Ok((l.split_evenly((left, 1)), r))
}

/// The residual autocorrelation of each output as stems at lags 1, 2, …, with the 95 %
/// bound ±1.96/√N (Ljung 16.6).
fn autocorrelation(area: &Area<'_>, outputs: &[String], whiteness: &[Whiteness]) -> Drawn {
    let caption = "Residual autocorrelation";
    let lags = whiteness.iter().map(|w| w.autocorrelation.len()).max().unwrap_or(0);
    if lags == 0 {
        return empty(area, caption, "no lag to show");
    }
    let bound = whiteness.iter().map(|w| w.bound).fold(0.0, f64::max);
    let y = range(whiteness.iter().flat_map(|w| w.autocorrelation.iter().copied()).chain([
        -1.3 * bound,
        1.3 * bound,
        0.0,
    ]));
    let x = 0.0..lags as f64 + 1.0;
    let grey = RGBColor(90, 90, 90).stroke_width(1);
    let mut keys: Vec<(String, Key)> = outputs
        .iter()
        .enumerate()
        .map(|(o, name)| (name.clone(), Key::Line(color(o).stroke_width(2))))
        .collect();
    keys.push(("±1.96/√N".into(), Key::Dashed(grey)));
    // The share of lags outside the bound goes under the axis, where there is room for it.
    let outside: Vec<String> = outputs
        .iter()
        .zip(whiteness)
        .map(|(name, w)| format!("{name} {:.0} %", 100.0 * w.fraction_outside))
        .collect();
    let x_desc = format!("lag τ [samples]   (lags outside ±1.96/√N: {})", outside.join(", "));
    let mut ch = chart(area, caption, &keys, x.clone(), y, &x_desc, "r(τ) [-]")?;
    let n = whiteness.len().max(1) as f64;
    for (o, w) in whiteness.iter().enumerate() {
        let shift = (o as f64 - (n - 1.0) / 2.0) * 0.25;
        let style = color(o).stroke_width(2);
        ch.draw_series(w.autocorrelation.iter().enumerate().map(|(k, r)| {
            PathElement::new(vec![(k as f64 + 1.0 + shift, 0.0), (k as f64 + 1.0 + shift, *r)], style)
        }))?;
    }
    dashed(&mut ch, &x, bound, grey, None)?;
    dashed(&mut ch, &x, -bound, grey, None)
}

/// The free parameters over the solver's iterations, each relative to its estimate.
fn trace(area: &Area<'_>, fit: &FitResult, free: &[&crate::estimate::ParameterEstimate]) -> Drawn {
    let caption = "Parameter trace over the iterations";
    let rows = &fit.parameter_trace;
    if rows.len() < 2 {
        return empty(area, caption, "no iteration recorded (closed form or all parameters fixed)");
    }
    // The trace holds the free entries of `parameters` in order; an entry appended after
    // the fit (an estimated input delay) has no column.
    let cols = rows[0].len().min(free.len());
    // Relative deviation from the estimate: short tick labels however close the trace ends
    // (an exact fit's 1 ± 1e-10 would need eleven digits a tick).
    let rel = |j: usize, v: f64| if free[j].value != 0.0 { v / free[j].value - 1.0 } else { f64::NAN };
    let y = range(rows.iter().flat_map(|r| (0..cols).map(move |j| rel(j, r[j]))).chain([0.0]));
    let x = 0.0..(rows.len() - 1).max(1) as f64;
    let mut ch = chart(area, caption, &[], x, y, "iteration", "θ / θ̂ − 1 [-] (0: the estimate)")?;
    for j in 0..cols {
        let style = color(j).stroke_width(2);
        let name = match &free[j].experiment {
            Some(e) => format!("{}[{e}]", free[j].name),
            None => free[j].name.clone(),
        };
        let points =
            rows.iter().enumerate().map(|(k, r)| (k as f64, rel(j, r[j]))).filter(|p| p.1.is_finite());
        ch.draw_series(LineSeries::new(points, style).point_size(2))?.label(name).legend(mark(style));
    }
    legend(&mut ch, SeriesLabelPosition::LowerRight)
}

/// Each free parameter's 95 % interval relative to its estimate \[%\], one row each,
/// labelled with the value and unit.
fn estimates(area: &Area<'_>, free: &[&crate::estimate::ParameterEstimate]) -> Drawn {
    let caption = "Estimates with 95 % intervals";
    if free.is_empty() {
        return empty(area, caption, "no free parameter");
    }
    let rel = |p: &crate::estimate::ParameterEstimate, v: f64| 100.0 * (v - p.value) / p.value.abs();
    let half = free
        .iter()
        .flat_map(|p| [rel(p, p.ci95[0]).abs(), rel(p, p.ci95[1]).abs()])
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let half = if half > 0.0 { 1.25 * half } else { 1.0 };
    let n = free.len() as f64;
    let fmt = move |v: &f64| super::draw::tick(*v, 2.0 * half);
    let mut ch = super::draw::under_header(area, caption, &[])?
        .y_label_area_size(20)
        .build_cartesian_2d(-half..half, -0.7..n - 0.2)?;
    ch.configure_mesh()
        .x_desc("95 % interval relative to the estimate [%]")
        .axis_desc_style((FONT, 15))
        .label_style((FONT, 13))
        .x_labels(7)
        .y_labels(0)
        .x_label_formatter(&fmt)
        .disable_y_mesh()
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .draw()?;
    let zero = RGBColor(150, 150, 150).stroke_width(1);
    ch.draw_series(std::iter::once(PathElement::new(vec![(0.0, -0.7), (0.0, n - 0.2)], zero)))?;
    for (i, p) in free.iter().enumerate() {
        let y = n - 1.0 - i as f64;
        let style = color(i).stroke_width(2);
        let (lo, hi) = (rel(p, p.ci95[0]), rel(p, p.ci95[1]));
        let name = match &p.experiment {
            Some(e) => format!("{}[{e}]", p.name),
            None => p.name.clone(),
        };
        let interval = if lo.is_finite() && hi.is_finite() {
            ch.draw_series([
                PathElement::new(vec![(lo, y), (hi, y)], style),
                PathElement::new(vec![(lo, y - 0.12), (lo, y + 0.12)], style),
                PathElement::new(vec![(hi, y - 0.12), (hi, y + 0.12)], style),
            ])?;
            let (below, above) = (p.value - p.ci95[0], p.ci95[1] - p.value);
            match (above - below).abs() <= 1e-6 * (above + below) {
                true => format!("± {} (± {} %)", format_eng(above, &p.unit, 2), value(hi)),
                // An asymmetric interval (the restricted intervals of instrumental variables).
                false => format!(
                    "+{} −{} (+{} % −{} %)",
                    format_eng(above, &p.unit, 2),
                    format_eng(below, &p.unit, 2),
                    value(hi),
                    value(-lo)
                ),
            }
        } else if p.at_bound {
            "(at a bound: no interval)".to_string()
        } else {
            "(no interval: not identifiable)".to_string()
        };
        ch.draw_series(std::iter::once(Circle::new((0.0, y), 4, style.filled())))?;
        let label = format!("{name} = {}  {interval}", format_eng(p.value, &p.unit, 6));
        ch.draw_series(std::iter::once(Text::new(label, (-half * 0.97, y + 0.42), (FONT, 14).into_font())))?;
    }
    Ok(())
}

/// The fit percentage and RMS residual of each output of each log.
fn table(area: &Area<'_>, comparisons: &[Comparison]) -> Drawn {
    area.draw_text("Fit per log", &(FONT, 17).into_font().color(&BLACK), (12, 8))?;
    let style = (FONT, 14).into_font().color(&BLACK);
    let (_, h) = area.dim_in_pixel();
    let fit_lines = ((h as i32 - 60) / 22).max(1) as usize;
    let mut y = 40;
    for (k, c) in comparisons.iter().enumerate() {
        if k + 1 == fit_lines && comparisons.len() > fit_lines {
            area.draw_text(&format!("… and {} more logs", comparisons.len() - k), &style, (12, y))?;
            break;
        }
        let per: Vec<String> = (0..c.outputs.len())
            .map(|i| {
                format!(
                    "{} {:.2} % (rms {} {})",
                    c.outputs[i],
                    c.metrics.fit_percent[i],
                    value(c.metrics.rms_residual[i]),
                    c.unit(i)
                )
            })
            .collect();
        area.draw_text(&format!("{}: {}", shorten(&c.experiment, 28), per.join(", ")), &style, (12, y))?;
        y += 22;
    }
    Ok(())
}

/// The residual whiteness of each output pooled over the logs (lags within each log).
fn pooled(comparisons: &[Comparison]) -> Vec<Whiteness> {
    let ny = comparisons.first().map_or(0, |c| c.outputs.len());
    (0..ny)
        .map(|o| {
            let e: Vec<Vec<f64>> = comparisons
                .iter()
                .map(|c| c.measured(o).iter().zip(c.simulated(o)).map(|(a, b)| a - b).collect())
                .collect();
            metrics::whiteness(&e.iter().map(Vec::as_slice).collect::<Vec<_>>(), WHITENESS_LAGS)
        })
        .collect()
}

/// Names joined by commas, cut to about 70 characters.
fn list(names: &[String]) -> String {
    shorten(&names.join(", "), 70)
}

/// `s` cut to `n` characters with an ellipsis.
fn shorten(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        format!("{}…", s.chars().take(n - 1).collect::<String>())
    }
}
