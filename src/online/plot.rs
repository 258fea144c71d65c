//! The observer plot: K̂_e over time (K̂_t = √(3/2) K̂_e on the right axis) and R̂_s over
//! time, one colour per log, the truth as dashed lines when known (thesis 5.1; MODEL.md
//! §2 for the K_e/K_t convention).

use super::Trajectory;
use crate::error::{Error, Result};
use crate::report::plot::draw::{
    Area, Drawn, FONT, PANEL, TITLE, WIDTH, color, legend, mark, range, tick, value,
};
use crate::report::plot::{decimate_min_max, plot_error};
use plotters::prelude::*;

/// Width of the K_t axis \[px\]; the R_s panel leaves the same room so that the time axes
/// line up.
const RIGHT_AXIS: u32 = 90;

/// `K_t = √(3/2) K_e` (MODEL.md §2).
const KT_PER_KE: f64 = 1.224_744_871_391_589;

/// The true parameters of a (simulated) log over time, drawn as a polyline through its
/// points (a plant whose K_e or R_s ramps within the record, as in thesis Exp 1).
#[derive(Clone, Debug, PartialEq)]
pub struct TrackTruth {
    /// Times \[s\] of the points, in the log's time, ascending; length n ≥ 1.
    pub t: Vec<f64>,
    /// Back-EMF constant K_e \[V s/rad\] (line-to-line RMS per mechanical rad/s) at `t`,
    /// length n.
    pub k_e: Vec<f64>,
    /// Stator resistance R_s \[Ω\] at `t`, length n.
    pub r_s: Vec<f64>,
}

impl TrackTruth {
    /// A truth constant over the record: K_e \[V s/rad\] and R_s \[Ω\] at every time.
    pub fn constant(k_e: f64, r_s: f64) -> Self {
        Self { t: vec![0.0], k_e: vec![k_e], r_s: vec![r_s] }
    }

    /// The polyline of `v` (K_e or R_s) over `[t_start, t_end]` \[s\] (the first and last
    /// values held to the ends), and its legend text: the value, or first → last.
    fn line(&self, v: &[f64], t_start: f64, t_end: f64, unit: &str) -> (Vec<(f64, f64)>, String) {
        let mut pts: Vec<(f64, f64)> = self.t.iter().map(|t| t.max(t_start)).zip(v.iter().copied()).collect();
        if let Some(&(t, y)) = pts.last()
            && t < t_end
        {
            pts.push((t_end, y));
        }
        let (first, last) = (v.first().copied().unwrap_or(f64::NAN), v.last().copied().unwrap_or(f64::NAN));
        let text = if first == last {
            format!("{} {unit}", value(first))
        } else {
            format!("{} → {} {unit}", value(first), value(last))
        };
        (pts, text)
    }
}

/// One log's observer run.
#[derive(Clone, Copy, Debug)]
pub struct TrackRun<'a> {
    /// Name of the log (legend).
    pub name: &'a str,
    /// The estimates over time.
    pub trajectory: &'a Trajectory,
    /// The truth, when known.
    pub truth: Option<&'a TrackTruth>,
}

/// The observer plot as SVG text: K̂_e \[V s/rad\] with K̂_t \[N m/A, peak A\] on the right
/// axis, and R̂_s \[Ω\], over time \[s\], one colour per run, the truth dashed.
///
/// # Errors
/// [`Error::InvalidOption`] (option `plot`) for no run, an empty trajectory, or a drawing
/// failure.
pub fn track_svg(runs: &[TrackRun<'_>]) -> Result<String> {
    let bad = |reason: String| Error::InvalidOption { option: "plot".into(), reason };
    if runs.is_empty() {
        return Err(bad("nothing to plot: no observer run".into()));
    }
    if let Some(r) = runs.iter().find(|r| r.trajectory.t.is_empty()) {
        return Err(bad(format!("the observer run over `{}` has no point", r.name)));
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, TITLE + 2 * PANEL + 80)).into_drawing_area();
        let drawn: Drawn = (|| {
            root.fill(&WHITE)?;
            let (head, body) = root.split_vertically(TITLE);
            let title = "MRAS observer: K_e and R_s estimates over time";
            head.draw_text(title, &(FONT, 20).into_font().color(&BLACK), (16, 10))?;
            let finals: Vec<String> = runs
                .iter()
                .map(|r| {
                    let f = &r.trajectory.final_estimate;
                    format!("{}: K_e {} V s/rad, R_s {} Ω", r.name, value(f.k_e), value(f.r_s))
                })
                .collect();
            let sub = format!("final: {}", finals.join("; "));
            head.draw_text(&sub, &(FONT, 15).into_font().color(&RGBColor(70, 70, 70)), (16, 38))?;
            let panels = body.split_evenly((2, 1));
            k_e(&panels[0], runs)?;
            r_s(&panels[1], runs)?;
            root.present()?;
            Ok(())
        })();
        drawn.map_err(plot_error)?;
    }
    Ok(svg)
}

/// The time axis of the runs: from the earliest first time to the latest last \[s\] (the
/// logs' own clock), never empty.
fn span(runs: &[TrackRun<'_>]) -> (f64, f64) {
    let start = runs.iter().filter_map(|r| r.trajectory.t.first().copied()).fold(f64::INFINITY, f64::min);
    let start = if start.is_finite() { start } else { 0.0 };
    let end = runs.iter().filter_map(|r| r.trajectory.t.last().copied()).fold(start, f64::max);
    (start, end.max(start + f64::MIN_POSITIVE.max(start.abs() * 1e-12)))
}

/// Share of the estimates at each end that may fall outside the value axis: an observer's
/// start-up transient (a spike of 30 times the value when the torque steps from standstill)
/// would otherwise squash the converged estimates and the truth into a few pixels.
const CLIP_SHARE: f64 = 0.01;

/// The value axis of one panel: the truth's values and the estimates between their
/// [`CLIP_SHARE`] and `1 − CLIP_SHARE` quantiles (over all runs), padded; and whether some
/// estimates lie outside it (the caption then says so).
fn robust_range(
    runs: &[TrackRun<'_>],
    estimates: fn(&Trajectory) -> &Vec<f64>,
    truth: fn(&TrackTruth) -> &Vec<f64>,
) -> (std::ops::Range<f64>, bool) {
    let mut all: Vec<f64> =
        runs.iter().flat_map(|r| estimates(r.trajectory).iter().copied()).filter(|v| v.is_finite()).collect();
    all.sort_by(f64::total_cmp);
    let at = |q: f64| all.get(((all.len().saturating_sub(1)) as f64 * q).round() as usize).copied();
    let (lo, hi) = (at(CLIP_SHARE), at(1.0 - CLIP_SHARE));
    let truths = runs.iter().filter_map(|r| r.truth).flat_map(|t| truth(t).iter().copied());
    let y = range(lo.into_iter().chain(hi).chain(truths));
    let clipped = all.first().is_some_and(|v| *v < y.start) || all.last().is_some_and(|v| *v > y.end);
    (y, clipped)
}

/// The caption's note when estimates lie outside the value axis.
fn clip_note(clipped: bool) -> &'static str {
    if clipped { "; axis clipped to the central 98 % of the estimates" } else { "" }
}

/// K̂_e over time with K̂_t on the secondary axis.
fn k_e(area: &Area<'_>, runs: &[TrackRun<'_>]) -> Drawn {
    let (t_start, t_end) = span(runs);
    let (y, clipped) = robust_range(runs, |r| &r.k_e, |t| &t.k_e);
    let (t_fmt, y_fmt) = (move |v: &f64| tick(*v, t_end - t_start), |v: &f64| tick(*v, y.end - y.start));
    let kt_fmt = |v: &f64| tick(*v, (y.end - y.start) * KT_PER_KE);
    let mut ch = ChartBuilder::on(area)
        .caption(
            format!(
                "Back-EMF constant K_e (torque constant K_t = √(3/2) K_e on the right){}",
                clip_note(clipped)
            ),
            (FONT, 17),
        )
        .margin_top(4)
        .margin_left(8)
        .margin_right(8)
        .x_label_area_size(44)
        .y_label_area_size(84)
        .right_y_label_area_size(RIGHT_AXIS)
        .build_cartesian_2d(t_start..t_end, y.clone())?
        .set_secondary_coord(t_start..t_end, y.start * KT_PER_KE..y.end * KT_PER_KE);
    ch.configure_mesh()
        .x_desc("t [s]")
        .y_desc("K_e [V s/rad] (line-to-line RMS, mechanical)")
        .axis_desc_style((FONT, 15))
        .label_style((FONT, 13))
        .x_label_formatter(&t_fmt)
        .y_label_formatter(&y_fmt)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .draw()?;
    ch.configure_secondary_axes()
        .y_desc("K_t [N m/A] (peak A)")
        .axis_desc_style((FONT, 15))
        .label_style((FONT, 13))
        .y_label_formatter(&kt_fmt)
        .draw()?;
    let width = ch.plotting_area().dim_in_pixel().0 as usize;
    for (i, r) in runs.iter().enumerate() {
        if let Some(pts) = band(&r.trajectory.t, &r.trajectory.k_e, &r.trajectory.k_e_se, width) {
            let fill = color(i).mix(0.15).filled();
            ch.draw_series(std::iter::once(Polygon::new(pts, fill)))?
                .label(format!("95 % interval, {}", r.name))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], fill));
        }
        let style = color(i).stroke_width(2);
        let pts = decimate_min_max(&r.trajectory.t, &r.trajectory.k_e, width);
        ch.draw_series(LineSeries::new(pts, style))?
            .label(format!("K_e estimate, {}", r.name))
            .legend(mark(style));
        if let Some(truth) = r.truth {
            let dash = color(i).stroke_width(1);
            let (pts, text) = truth.line(&truth.k_e, t_start, t_end, "V s/rad");
            ch.draw_series(DashedLineSeries::new(pts, 8, 5, dash))?
                .label(format!("truth {text}, {}", r.name))
                .legend(mark(dash));
        }
    }
    ch.configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .label_font((FONT, 13))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .draw()?;
    Ok(())
}

/// R̂_s over time.
fn r_s(area: &Area<'_>, runs: &[TrackRun<'_>]) -> Drawn {
    let (t_start, t_end) = span(runs);
    let (y, clipped) = robust_range(runs, |r| &r.r_s, |t| &t.r_s);
    // The K_e panel's right margin (8) and K_t axis, less the common chart's margin (24).
    let (w, _) = area.dim_in_pixel();
    let (area, _) = area.split_horizontally(w - (RIGHT_AXIS + 8 - 24));
    let mut ch = crate::report::plot::draw::chart(
        &area,
        &format!("Stator resistance R_s{}", clip_note(clipped)),
        &[],
        t_start..t_end,
        y,
        "t [s]",
        "R_s [Ω]",
    )?;
    let width = ch.plotting_area().dim_in_pixel().0 as usize;
    for (i, r) in runs.iter().enumerate() {
        if let Some(pts) = band(&r.trajectory.t, &r.trajectory.r_s, &r.trajectory.r_s_se, width) {
            let fill = color(i).mix(0.15).filled();
            ch.draw_series(std::iter::once(Polygon::new(pts, fill)))?
                .label(format!("95 % interval, {}", r.name))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], fill));
        }
        let style = color(i).stroke_width(2);
        let pts = decimate_min_max(&r.trajectory.t, &r.trajectory.r_s, width);
        ch.draw_series(LineSeries::new(pts, style))?
            .label(format!("R_s estimate, {}", r.name))
            .legend(mark(style));
        if let Some(truth) = r.truth {
            let dash = color(i).stroke_width(1);
            let (pts, text) = truth.line(&truth.r_s, t_start, t_end, "Ω");
            ch.draw_series(DashedLineSeries::new(pts, 8, 5, dash))?
                .label(format!("truth {text}, {}", r.name))
                .legend(mark(dash));
        }
    }
    legend(&mut ch, SeriesLabelPosition::LowerRight)
}

/// The 95 % band `v ± 1.96 se` over `t` as a closed outline (the upper edge forward, the
/// lower back) of at most about `2 width` points (evenly strided, the last kept); `None`
/// without standard errors.
fn band(t: &[f64], v: &[f64], se: &[f64], width: usize) -> Option<Vec<(f64, f64)>> {
    if se.len() != t.len() || t.is_empty() {
        return None;
    }
    let stride = t.len().div_ceil(width.max(1)).max(1);
    let mut idx: Vec<usize> = (0..t.len()).step_by(stride).collect();
    if idx.last() != Some(&(t.len() - 1)) {
        idx.push(t.len() - 1);
    }
    let finite = |k: &usize| v[*k].is_finite() && se[*k].is_finite();
    let upper = idx.iter().filter(|k| finite(k)).map(|&k| (t[k], v[k] + 1.96 * se[k]));
    let lower: Vec<(f64, f64)> =
        idx.iter().filter(|k| finite(k)).map(|&k| (t[k], v[k] - 1.96 * se[k])).collect();
    Some(upper.chain(lower.into_iter().rev()).collect())
}
