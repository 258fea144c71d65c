//! Time windows and gaps of a time column: which rows a window `[from, to]` keeps, and where
//! a time column breaks into uniformly sampled segments.
//!
//! A step `t[k] − t[k−1]` of a time column sampled every h is one of three things:
//! - regular: within [`TIME_TOLERANCE`](super::TIME_TOLERANCE) h of h (what
//!   [`Experiment::try_from_time`](super::Experiment::try_from_time) accepts);
//! - a **gap** ([`is_gap`]): not positive (a step back or a repeated time), or longer than
//!   [`GAP_FACTOR`] h (a pause, dropped samples, a logger restart);
//! - irregular: anything else (a step between 1.25 h and 1.5 h, or a positive one below
//!   0.75 h), which no segmentation explains and stays an error.
//!
//! [`time_segments`] applies this to a whole column with h the median step, robust to a
//! few gaps; nothing here knows what the other columns hold.

use std::ops::Range;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A step longer than `GAP_FACTOR · h` is a gap: 1.5, halfway between a regular step (at
/// most 1.25 h by [`TIME_TOLERANCE`](super::TIME_TOLERANCE)) and one dropped sample (2 h).
pub const GAP_FACTOR: f64 = 1.5;

/// Whether a time step `dt` \[s\] is a gap for the sample time `h` \[s\]: `dt ≤ 0` (a step
/// back or a repeated time), `dt > GAP_FACTOR · h`, or `dt` NaN.
pub fn is_gap(dt: f64, h: f64) -> bool {
    !(dt > 0.0 && dt <= GAP_FACTOR * h)
}

/// The [`Error::NonUniformTime`] of a step `dt` \[s\] at data row `row` of the time column
/// `column` against the mean step `expected` \[s\] and the relative tolerance, with its gap
/// flag set by [`is_gap`] (for a positive mean step).
pub(crate) fn non_uniform_time(column: &str, row: usize, dt: f64, expected: f64, tolerance: f64) -> Error {
    let gap = expected > 0.0 && is_gap(dt, expected);
    Error::NonUniformTime { column: column.to_string(), row, dt, expected, tolerance, gap }
}

/// A time window `from ≤ t ≤ to` \[s\] on a time column already in seconds; `None` leaves
/// that side open. Both ends are inclusive: a sample exactly at `from` or `to` is kept.
///
/// Compared bit for bit (`-0.0 ≠ 0.0`), so that it can be `Eq`.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct TimeWindow {
    /// First time kept \[s\], inclusive; `None`: from the first sample.
    pub from: Option<f64>,
    /// Last time kept \[s\], inclusive; `None`: to the last sample.
    pub to: Option<f64>,
}

impl PartialEq for TimeWindow {
    fn eq(&self, other: &Self) -> bool {
        let bits = |x: Option<f64>| x.map(f64::to_bits);
        bits(self.from) == bits(other.from) && bits(self.to) == bits(other.to)
    }
}

impl Eq for TimeWindow {}

impl TimeWindow {
    /// Whether both sides are open (the window keeps every sample).
    pub fn is_open(&self) -> bool {
        self.from.is_none() && self.to.is_none()
    }

    /// Checks the window.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] with option `from` (or `to`) for a non-finite end, and
    /// `from` for `from ≥ to`.
    pub fn check(&self) -> Result<()> {
        for (option, x) in [("from", self.from), ("to", self.to)] {
            if let Some(x) = x.filter(|x| !x.is_finite()) {
                return Err(Error::InvalidOption {
                    option: option.into(),
                    reason: format!("{x} is not a finite time in seconds"),
                });
            }
        }
        if let (Some(from), Some(to)) = (self.from, self.to)
            && from >= to
        {
            return Err(Error::InvalidOption {
                option: "from".into(),
                reason: format!("the window start {from} s is not before its end {to} s"),
            });
        }
        Ok(())
    }

    /// Whether the window keeps time `t` \[s\]: `from ≤ t ≤ to`.
    pub fn contains(&self, t: f64) -> bool {
        self.from.is_none_or(|f| t >= f) && self.to.is_none_or(|e| t <= e)
    }

    /// `[from, to]` in words, e.g. `[0.5 s, 1.2 s]` or `[0.5 s, end]`.
    pub fn describe(&self) -> String {
        let side = |x: Option<f64>, open: &str| x.map_or(open.to_string(), |x| format!("{x} s"));
        format!("[{}, {}]", side(self.from, "start"), side(self.to, "end"))
    }
}

/// The rows of a time column kept by a window, cut at its gaps.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeSegments {
    /// Rows in the window, whether or not in a kept segment.
    pub in_window: usize,
    /// Reference step h \[s\]: the median of the steps between consecutive rows in the window
    /// (NaN when there is none).
    pub h: f64,
    /// Maximal runs of consecutive rows, in file order, that lie in the window and hold no
    /// gap for `h` ([`is_gap`]); each a range of 0-based rows of the column.
    pub segments: Vec<Range<usize>>,
}

/// Cuts the time column `t` \[s\] (length N) to `window` and at its gaps.
///
/// A new segment starts where a row follows one outside the window, or where the step
/// from the previous row is a gap ([`is_gap`]) for the median step h of the rows in the
/// window. The steps inside a segment are not otherwise checked: building an
/// [`Experiment`](super::Experiment) from it does that.
pub fn time_segments(t: &[f64], window: &TimeWindow) -> TimeSegments {
    let inside: Vec<bool> = t.iter().map(|&x| window.contains(x)).collect();
    let in_window = inside.iter().filter(|&&b| b).count();
    let mut steps: Vec<f64> =
        (1..t.len()).filter(|&k| inside[k] && inside[k - 1]).map(|k| t[k] - t[k - 1]).collect();
    let h = if steps.is_empty() {
        f64::NAN
    } else {
        let mid = steps.len() / 2;
        *steps.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let mut segments: Vec<Range<usize>> = Vec::new();
    for k in (0..t.len()).filter(|&k| inside[k]) {
        match segments.last_mut() {
            Some(s) if s.end == k && !is_gap(t[k] - t[k - 1], h) => s.end = k + 1,
            _ => segments.push(k..k + 1),
        }
    }
    TimeSegments { in_window, h, segments }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_and_gaps() {
        let mut t: Vec<f64> = (0..10).map(f64::from).collect();
        t.extend((20..25).map(f64::from)); // a pause after 9
        t.extend((3..6).map(f64::from)); // a step back
        let all = time_segments(&t, &TimeWindow::default());
        assert_eq!((all.in_window, all.h), (18, 1.0));
        assert_eq!(all.segments, [0..10, 10..15, 15..18]);
        let w = TimeWindow { from: Some(4.0), to: Some(21.0) };
        let cut = time_segments(&t, &w);
        assert_eq!(cut.segments, [4..10, 10..12, 16..18]);
        assert!(TimeWindow { from: Some(2.0), to: Some(2.0) }.check().is_err());
        assert!(TimeWindow { from: Some(f64::NAN), to: None }.check().is_err());
        assert!(is_gap(0.0, 1.0) && is_gap(1.51, 1.0) && !is_gap(1.5, 1.0) && is_gap(f64::NAN, 1.0));
    }
    /// The time error's message suggests splitting the log exactly at the steps `is_gap`
    /// calls gaps (the error restates the rule).
    #[test]
    fn the_time_error_hints_a_split_exactly_at_gaps() {
        for dt in [-1.0, 0.0, 1e-9, 0.5, 1.0, 1.25, 1.5, 1.5000001, 2.0, 1e300, f64::INFINITY, f64::NAN] {
            for h in [1.0, 1e-4] {
                let (dt, tolerance) = (dt * h, crate::data::TIME_TOLERANCE);
                let e = non_uniform_time("t", 1, dt, h, tolerance);
                assert_eq!(e.to_string().contains("--split-gaps"), is_gap(dt, h), "{dt} {h}");
            }
        }
    }
}
