//! Drawing helpers shared by the plots: colours, one chart per panel with labelled axes,
//! legends, number formatting and axis ranges.

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::ops::Range;

/// Result of drawing on the SVG backend.
pub(crate) type Drawn<T = ()> = std::result::Result<T, Box<dyn std::error::Error>>;

/// A drawing area of the SVG backend.
pub(crate) type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;

/// A cartesian chart of the SVG backend.
pub(crate) type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Width of the figures \[px\].
pub(crate) const WIDTH: u32 = 1600;
/// Height of one panel \[px\].
pub(crate) const PANEL: u32 = 230;
/// Height of the title strip \[px\].
pub(crate) const TITLE: u32 = 64;
/// Font family of every text (the viewer's sans-serif).
pub(crate) const FONT: &str = "sans-serif";

/// Measured data.
pub(crate) const MEASURED: RGBColor = RGBColor(40, 40, 40);
/// Distinct colours for series (simulated outputs, parameters, runs): the Tableau 10.
pub(crate) const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// The i-th palette colour (cycling).
pub(crate) fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// A chart on `area` under a [`header`] (the caption on the left, the legend `keys` on
/// the right, wrapped onto further rows when too wide, so that neither covers data), both
/// axes labelled (`x_desc`, `y_desc` carry the unit), a light grid, and tick labels of at
/// most 4 significant digits.
pub(crate) fn chart<'a, 'b>(
    area: &'a Area<'b>,
    caption: &str,
    keys: &[(String, Key)],
    x: Range<f64>,
    y: Range<f64>,
    x_desc: &str,
    y_desc: &str,
) -> Drawn<Chart<'a, 'b>> {
    let (x_span, y_span) = (x.end - x.start, y.end - y.start);
    let mut chart =
        under_header(area, caption, keys)?.margin_bottom(4).y_label_area_size(84).build_cartesian_2d(x, y)?;
    let x_fmt = |v: &f64| tick(*v, x_span);
    let y_fmt = |v: &f64| tick(*v, y_span);
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .axis_desc_style((FONT, 15))
        .label_style((FONT, 13))
        .x_labels(8)
        .y_labels(6)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .draw()?;
    Ok(chart)
}

/// Height of a panel's header row \[px\] (more when the legend wraps: [`header`]).
pub(crate) const HEADER: u32 = 30;

/// How a legend key is drawn.
#[derive(Clone, Copy)]
pub(crate) enum Key {
    /// A line.
    Line(ShapeStyle),
    /// A filled band.
    Band(ShapeStyle),
    /// A dashed line.
    Dashed(ShapeStyle),
    /// A point (a circle filled or outlined by the style).
    Dot(ShapeStyle),
}

/// A panel's header row: `caption` at the left, the legend `keys` from the right edge,
/// so that neither covers data; returns the header's height \[px\], [`HEADER`] or more,
/// under which the chart goes. Text widths are estimated generously for a sans-serif
/// font (8 px a character at 17 px, 6.5 px at 13 px). Keys that do not fit on the
/// caption's line wrap onto further rows ([`key_layout`]); a label too long for a row is
/// cut with "…".
pub(crate) fn header(area: &Area<'_>, caption: &str, keys: &[(String, Key)]) -> Drawn<u32> {
    let (w, _) = area.dim_in_pixel();
    area.draw_text(caption, &(FONT, 17).into_font().color(&BLACK), (12, 6))?;
    let chars = |s: &str| s.chars().count() as f64;
    let label_width = |label: &str| (6.5 * chars(label)) as i32;
    let caption_end = 12 + (8.0 * chars(caption)) as i32 + 16;
    let widths: Vec<i32> = keys.iter().map(|(l, _)| label_width(l)).collect();
    let (slots, height) = key_layout(w as i32, caption_end, &widths);
    let font = (FONT, 13).into_font().color(&RGBColor(30, 30, 30));
    for ((label, key), slot) in keys.iter().zip(slots) {
        let (x, y) = (slot.x, slot.y);
        match *key {
            Key::Line(style) => area.draw(&PathElement::new(vec![(x, y), (x + 24, y)], style))?,
            Key::Band(style) => area.draw(&Rectangle::new([(x, y - 6), (x + 24, y + 6)], style))?,
            Key::Dashed(style) => {
                area.draw(&PathElement::new(vec![(x, y), (x + 9, y)], style))?;
                area.draw(&PathElement::new(vec![(x + 15, y), (x + 24, y)], style))?;
            }
            Key::Dot(style) => area.draw(&Circle::new((x + 12, y), 5, style))?,
        }
        if slot.label >= label_width(label) {
            area.draw_text(label, &font, (x + 30, y - 7))?;
        } else {
            // As many characters as the slot holds, the last one an ellipsis.
            let keep = (f64::from(slot.label) / 6.5) as usize;
            if keep > 0 {
                let cut: String = label.chars().take(keep - 1).chain(['…']).collect();
                area.draw_text(&cut, &font, (x + 30, y - 7))?;
            }
        }
    }
    Ok(height)
}

/// Height of each legend row below the caption's line \[px\].
pub(crate) const KEY_ROW: u32 = 20;

/// Where a legend key goes in a header \[px\]: the left end of its sample `x`, the middle
/// of its row `y`, and the width of its label (less than asked when cut to fit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Slot {
    /// Left end of the key's sample; the label starts 30 px right of it.
    pub x: i32,
    /// Middle of the key's row.
    pub y: i32,
    /// Width left for the label.
    pub label: i32,
}

/// The legend's layout in the header of a panel `width` px wide whose caption ends at
/// `caption_end`, for keys with labels `labels` px wide (each key takes a 30 px sample
/// before its label and a 12 px gap after it; the rows end 24 px from the panel's right
/// edge): each key's [`Slot`] and the header's height. The keys fill, in order and
/// right-aligned, the caption's line and then further rows of [`KEY_ROW`] px under it
/// starting 12 px from the left edge; a key wider than a row has a row of its own and
/// its label cut to fit. Keys that all fit on the caption's line stay on it, the header
/// [`HEADER`] px high.
pub(crate) fn key_layout(width: i32, caption_end: i32, labels: &[i32]) -> (Vec<Slot>, u32) {
    const SAMPLE: i32 = 30;
    const GAP: i32 = 12;
    let right = width - 24;
    // Rows of (key, key width), the caption's line first.
    let mut rows: Vec<Vec<(usize, i32)>> = vec![Vec::new()];
    let mut used = 0;
    for (k, &label) in labels.iter().enumerate() {
        let key = SAMPLE + label.max(0) + GAP;
        let start = if rows.len() == 1 { caption_end } else { 12 };
        if start + used + key > right && (rows.len() == 1 || used > 0) {
            rows.push(Vec::new());
            used = 0;
        }
        let room = right - if rows.len() == 1 { caption_end } else { 12 };
        let key = key.min(room.max(SAMPLE + GAP));
        rows.last_mut().expect("a row").push((k, key));
        used += key;
    }
    let mut slots = vec![Slot { x: 0, y: 0, label: 0 }; labels.len()];
    for (r, row) in rows.iter().enumerate() {
        let mut x = right - row.iter().map(|(_, w)| w).sum::<i32>();
        let y = 14 + KEY_ROW as i32 * r as i32;
        for &(k, key) in row {
            slots[k] = Slot { x, y, label: key - SAMPLE - GAP };
            x += key;
        }
    }
    (slots, HEADER + KEY_ROW * (rows.len() as u32 - 1))
}

/// The [`header`] of a panel drawn, and a chart builder placed under it (the header's
/// height above, 8 px left, 24 px right, 44 px for the x labels), for the caller to give
/// its y label width (and bottom margin) and coordinates.
pub(crate) fn under_header<'a, 'b>(
    area: &'a Area<'b>,
    caption: &str,
    keys: &[(String, Key)],
) -> Drawn<ChartBuilder<'a, 'b, SVGBackend<'b>>> {
    let top = header(area, caption, keys)?;
    let mut builder = ChartBuilder::on(area);
    builder.margin_top(top).margin_left(8).margin_right(24).x_label_area_size(44);
    Ok(builder)
}

/// The legend of `chart`'s labelled series, in its upper-right corner on a translucent
/// white box.
pub(crate) fn legend<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>, position: SeriesLabelPosition) -> Drawn {
    chart
        .configure_series_labels()
        .position(position)
        .label_font((FONT, 13))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .margin(6)
        .draw()?;
    Ok(())
}

/// A legend mark: a short line in `style`.
pub(crate) fn mark(style: ShapeStyle) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style)
}

/// A horizontal dashed line at `y` over `x`, labelled in the legend when `label` is given.
pub(crate) fn dashed(
    chart: &mut Chart<'_, '_>,
    x: &Range<f64>,
    y: f64,
    style: ShapeStyle,
    label: Option<&str>,
) -> Drawn {
    let s = chart.draw_series(DashedLineSeries::new(vec![(x.start, y), (x.end, y)], 6, 4, style))?;
    if let Some(l) = label {
        s.label(l).legend(mark(style));
    }
    Ok(())
}

/// A message in the middle of an empty panel.
pub(crate) fn empty(area: &Area<'_>, caption: &str, message: &str) -> Drawn {
    let (w, h) = area.dim_in_pixel();
    area.draw_text(caption, &(FONT, 17).into_font().color(&BLACK), (12, 8))?;
    area.draw_text(
        message,
        &(FONT, 14).into_font().color(&RGBColor(110, 110, 110)),
        (w as i32 / 4, h as i32 / 2),
    )?;
    Ok(())
}

/// The range of the finite `values`, padded by 5 % (±1 around a single value, \[0, 1\]
/// without any).
pub(crate) fn range(values: impl IntoIterator<Item = f64>) -> Range<f64> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo > hi {
        return 0.0..1.0;
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { lo.abs().max(1.0) * 0.05 };
    lo - pad..hi + pad
}

/// A tick label on an axis spanning `span`: 4 significant digits, or as many more as
/// tell ticks `span/8` apart; exponent form outside [1e-3, 1e5), and 0 for what rounding
/// left of zero (below 10⁻⁹ of the span).
pub(crate) fn tick(v: f64, span: f64) -> String {
    if v == 0.0 || v.abs() < 1e-9 * span.abs() {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.2e}");
    }
    // Four significant digits, or more when the ticks are closer than that resolves
    // (0.53885, 0.5389, 0.53895 on a span of 2e-4).
    let by_size = 3 - a.log10().floor() as i32;
    let step = span.abs() / 8.0;
    let by_step = if step > 0.0 && step.is_finite() { 1 - step.log10().floor() as i32 } else { 0 };
    let decimals = by_size.max(by_step).clamp(0, 12) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

/// A value with 5 significant digits (exponent form outside [1e-3, 1e5)).
pub(crate) fn value(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        return format!("{v:.4e}");
    }
    let decimals = if a == 0.0 { 0 } else { (4 - a.log10().floor() as i32).max(0) as usize };
    format!("{v:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::{HEADER, KEY_ROW, Slot, key_layout, tick};

    #[test]
    fn legend_that_fits_stays_on_the_caption_line() {
        // The time panel of `id` (992 px, caption "id measured and simulated"): as before,
        // right-aligned from 24 px before the right edge, a key 30 + label + 12 px wide.
        let (slots, height) = key_layout(992, 228, &[78, 84]);
        assert_eq!(height, HEADER);
        let x0 = 992 - 24 - (30 + 78 + 12) - (30 + 84 + 12);
        assert_eq!(slots, [Slot { x: x0, y: 14, label: 78 }, Slot { x: x0 + 120, y: 14, label: 84 }]);
        assert_eq!(key_layout(992, 228, &[]), (vec![], HEADER));
        // Exactly filling the room between the caption and the margin still fits.
        let (slots, height) = key_layout(600, 600 - 24 - 142, &[100]);
        assert_eq!((slots[0].x, height), (600 - 24 - 142, HEADER));
    }

    #[test]
    fn legend_too_wide_wraps_inside_the_panel() {
        let (width, caption_end) = (400, 220);
        let labels = [60, 300, 120, 900, 40, 50];
        let (slots, height) = key_layout(width, caption_end, &labels);
        // Rows: 60 beside the caption; 300; 120; 900 cut; 40 and 50.
        assert_eq!(height, HEADER + 4 * KEY_ROW);
        for (k, (s, &label)) in slots.iter().zip(&labels).enumerate() {
            // Inside the panel, above the chart (which starts `height` down), cut only
            // when wider than a row.
            assert!(s.x >= 12 && s.x + 30 + s.label <= width - 24, "key {k}: {s:?}");
            assert!(s.y - 7 >= 0 && s.y + 7 <= height as i32, "key {k}: {s:?} under {height}");
            assert!(s.label == label || (s.label < label && s.x == 12), "key {k}: {s:?}");
            // Right of the caption on its line; keys in order, never overlapping.
            assert!(s.y > 14 || s.x >= caption_end, "key {k}: {s:?}");
            if let Some(next) = slots.get(k + 1) {
                assert!(next.y > s.y || (next.y == s.y && next.x >= s.x + 30 + s.label + 12));
            }
        }
        assert_eq!(slots[0].y, 14, "the first key fits beside the caption");
        assert_eq!(slots[3], Slot { x: 12, y: slots[3].y, label: 400 - 24 - 12 - 42 });
        // Rows are right-aligned: the last key of each row ends at the margin.
        for (k, s) in slots.iter().enumerate() {
            if slots.get(k + 1).is_none_or(|n| n.y > s.y) {
                assert_eq!(s.x + 30 + s.label + 12, width - 24, "key {k}");
            }
        }
        // A caption wider than the panel sends every key under it.
        let (slots, _) = key_layout(400, 900, &[40]);
        assert_eq!(slots[0].y, 14 + KEY_ROW as i32);
    }

    #[test]
    fn ticks_tell_neighbours_apart() {
        // A narrow span around 0.5389: neighbouring ticks must differ as text.
        let labels: Vec<String> = (0..5).map(|k| tick(0.53885 + 2.5e-5 * f64::from(k), 2e-4)).collect();
        for w in labels.windows(2) {
            assert_ne!(w[0], w[1], "{labels:?}");
        }
        assert_eq!(tick(0.5, 1.0), "0.5");
        assert_eq!(tick(200.0, 400.0), "200");
        assert_eq!(tick(1e-12, 10.0), "0");
        assert_eq!(tick(4e-5, 8e-5), "4.00e-5");
    }
}
