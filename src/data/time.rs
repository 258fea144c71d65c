//! The time column: its uniformity tolerance, the row-by-row check a reader runs while the
//! rows stream in ([`TimeSteps`]), and the mean step h of a column.

use super::all_finite;
use super::segments::non_uniform_time;
use crate::error::{Error, Result};

/// Uniformity tolerance of a time column, relative to the step h: every step
/// `t[k] − t[k−1]` must lie within `0.25 h` of the mean step h, and every `t[k]` within
/// `h/2` of `t[0] + k h`.
///
/// The first test names the row of a dropped, repeated or shifted sample; the second
/// catches a slow drift of the rate. Both admit the rounding of times written with 6
/// decimals at any rate up to 100 kHz.
pub const TIME_TOLERANCE: f64 = 0.25;

/// Whether a table reader ([`super::read_table_with`]) checks
/// the time column (the first wanted column) with [`TimeSteps::push`] while the rows
/// stream in. Default [`TimeCheck::Streaming`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeCheck {
    /// The reader checks the time column row by row and stops at the first bad step
    /// ([`Error::NonUniformTime`]), as [`super::csv::read_table_with`] always does. The default.
    #[default]
    Streaming,
    /// The reader reads the time column as any other wanted column (each value a finite
    /// number, else [`Error::NonFinite`] naming it) and leaves its steps unchecked: for a
    /// caller that checks them itself, e.g. one that keeps a window of the rows or cuts the
    /// column at its gaps ([`super::segments::time_segments`]).
    Skip,
}

/// Incremental check of a time column `t_k` \[s\], one row at a time, so that a reader can
/// stop at the first bad row instead of after the whole file; [`TimeSteps::finish`] then
/// applies the checks that need the mean step h of the whole column.
///
/// Row by row ([`TimeSteps::push`]): every value finite ([`Error::NonFinite`]), every step
/// positive, and every step within `[0.6, 5/3]` of the mean of the steps before it
/// ([`Error::NonUniformTime`], reported with [`TIME_TOLERANCE`]). A column that passes
/// [`TIME_TOLERANCE`] against its mean h has every step and every partial mean within
/// `[0.75 h, 1.25 h]`, so the row-by-row test never refuses a column the final one accepts;
/// it only names a grossly dropped or repeated sample early (a repeated row at row 1).
/// A gap ([`super::is_gap`]) is an error here like any other bad step (its message says so and
/// how to split the log); [`super::segments::time_segments`] cuts a column at its gaps instead.
#[derive(Clone, Debug)]
pub struct TimeSteps {
    column: String,
    first: f64,
    last: f64,
    rows: usize,
}

impl TimeSteps {
    /// A checker for the time column called `column` (the name the errors carry).
    pub fn new(column: impl Into<String>) -> Self {
        Self { column: column.into(), first: 0.0, last: 0.0, rows: 0 }
    }

    /// Number of values pushed.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Checks the next value `t` \[s\], of 0-based row [`TimeSteps::rows`].
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/Inf; [`Error::NonUniformTime`] for a step that is not
    /// positive (with the mean step so far as `expected`) or is far from the mean of the
    /// earlier steps.
    pub fn push(&mut self, t: f64) -> Result<()> {
        let row = self.rows;
        if !t.is_finite() {
            return Err(Error::NonFinite { column: self.column.clone(), row, value: t });
        }
        if row > 0 {
            let dt = t - self.last;
            let bad = |expected: f64| non_uniform_time(&self.column, row, dt, expected, TIME_TOLERANCE);
            if dt <= 0.0 {
                return Err(bad((t - self.first) / row as f64));
            }
            if row > 1 {
                let before = (self.last - self.first) / (row - 1) as f64;
                if !(0.6 * before..=before / 0.6).contains(&dt) {
                    return Err(bad(before));
                }
            }
        } else {
            self.first = t;
        }
        self.last = t;
        self.rows += 1;
        Ok(())
    }

    /// [`push`](Self::push) of every value of `t` \[s\] in order, with the same result and
    /// the same error (the first bad row's).
    ///
    /// A fresh checker first tests, without a division per row, that `t` is finite and that
    /// every step lies within 20 % of the column's mean step. Then every partial
    /// mean lies there too, every step is within `[0.67, 1.5]` of the mean before it, well
    /// inside [`push`](Self::push)'s `[0.6, 5/3]`, and no row can fail: the state is set at
    /// once. Any other column goes row by row.
    ///
    /// # Errors
    /// Those of [`push`](Self::push).
    pub fn push_all(&mut self, t: &[f64]) -> Result<()> {
        if let (0, [first, .., last]) = (self.rows, t)
            && all_finite(t)
            && steps_within(t, SAFE_STEP)
        {
            (self.first, self.last, self.rows) = (*first, *last, t.len());
            return Ok(());
        }
        t.iter().try_for_each(|&x| self.push(x))
    }

    /// Mean step h = `(t[N−1] − t[0])/(N − 1)` \[s\] of the column whose N values were pushed,
    /// after the checks that need it: every step within [`TIME_TOLERANCE`] h of h and every
    /// `t[k]` within `h/2` of `t[0] + k h`. `t` is the column itself.
    ///
    /// # Errors
    /// [`Error::InvalidSampleTime`] for fewer than two values or a non-finite h;
    /// [`Error::NonUniformTime`] naming the first row outside either bound.
    pub fn finish(&self, t: &[f64]) -> Result<f64> {
        let n = t.len();
        if n < 2 {
            return Err(Error::InvalidSampleTime { h: f64::NAN });
        }
        let h = (t[n - 1] - t[0]) / (n - 1) as f64;
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidSampleTime { h });
        }
        let bad = |row: usize| non_uniform_time(&self.column, row, t[row] - t[row - 1], h, TIME_TOLERANCE);
        if let Some(k) = (1..n).find(|&k| ((t[k] - t[k - 1]) - h).abs() > TIME_TOLERANCE * h) {
            return Err(bad(k));
        }
        if let Some(k) = (1..n).find(|&k| (t[k] - (t[0] + k as f64 * h)).abs() > 0.5 * h) {
            return Err(bad(k));
        }
        Ok(h)
    }
}

/// Relative bound on every step's distance from the mean step under which
/// [`TimeSteps::push_all`] needs no row-by-row test.
const SAFE_STEP: f64 = 0.2;

/// Whether every step of `t` (N ≥ 2, finite) is within `tolerance` (relative) of the mean
/// step `(t[N−1] − t[0])/(N − 1)`, which must be positive and a normal number (an overflowed
/// or subnormal mean goes row by row): a branch-free loop that vectorises (`t` finite: no
/// NaN to compare).
fn steps_within(t: &[f64], tolerance: f64) -> bool {
    let n = t.len();
    let h = (t[n - 1] - t[0]) / (n - 1) as f64;
    let bound = tolerance * h;
    let outside: usize = t[1..].iter().zip(t).map(|(b, a)| usize::from(((b - a) - h).abs() > bound)).sum();
    h.is_normal() && h > 0.0 && outside == 0
}

/// Mean step of a uniform, strictly increasing time vector (N ≥ 2), checked sample by
/// sample with [`TimeSteps`].
pub(super) fn uniform_step(t: &[f64], column: &str) -> Result<f64> {
    let mut steps = TimeSteps::new(column);
    steps.push_all(t)?;
    steps.finish(t)
}
