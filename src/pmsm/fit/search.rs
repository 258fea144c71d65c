//! Searches of one nuisance value by whole fits or one-step losses: a scan, then a
//! golden-section search on the bracket around its best point (Kiefer, *Proc. AMS* 4 (1953)
//! 502–506) or Brent's method there (Brent, *Algorithms for Minimization without
//! Derivatives*, 1973, ch. 5: golden sections and parabolic steps; argmin's `BrentOpt`), the
//! scan taken whole or walked from a value found before ([`walk_search`]), and the range of
//! the controller's phase-locked loop that the voltage input's and the PWM fit's searches
//! share.

use crate::error::{Error, Result};

/// Range of the speed-estimator bandwidth searched \[rad/s\]: 2π·10 Hz to 2π·2 kHz.
pub const SPEED_PLL_RANGE: (f64, f64) = (62.83185307179586, 12_566.370614359172);
/// Points of the coarse scan before the golden-section refinement (and of the PWM loop's
/// search when it scans no likelihood-ratio set).
pub(crate) const COARSE: usize = 16;
/// Golden-section steps (each shrinks the bracket by 0.618: 24 steps ≈ 1e-5 in ln α).
const GOLDEN_STEPS: usize = 24;

/// The value in `range` with the lowest `loss`: an evenly spaced scan, then a golden-section
/// search in the bracket around the best point; on the logarithm when `log` (a positive
/// range).
pub(crate) fn golden_search(
    range: (f64, f64),
    log: bool,
    mut loss: impl FnMut(f64) -> Result<f64>,
) -> Result<f64> {
    let (to, from) = maps(log);
    let mut loss = move |x: f64| loss(from(x));
    let (lo, hi) = (to(range.0), to(range.1));
    let grid = grid(lo, hi, COARSE);
    let mut values = Vec::with_capacity(COARSE);
    for &x in &grid {
        values.push(loss(x)?);
    }
    let (mut a, mut b) = bracket(range, &grid, &values)?.1;
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - r * (b - a), a + r * (b - a));
    let (mut fc, mut fd) = (loss(c)?, loss(d)?);
    for _ in 0..GOLDEN_STEPS {
        if fc <= fd {
            (b, d, fd) = (d, c, fc);
            c = b - r * (b - a);
            fc = loss(c)?;
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + r * (b - a);
            fd = loss(d)?;
        }
    }
    Ok(from(if fc <= fd { c } else { d }))
}

/// `points` (at least 2) evenly spaced values from `lo` to `hi`, both included: the scans'
/// grid (on the logarithm for a log search).
pub(crate) fn grid(lo: f64, hi: f64, points: usize) -> Vec<f64> {
    (0..points).map(|i| lo + (hi - lo) * i as f64 / (points - 1) as f64).collect()
}

/// The best point of a scan `grid` (values `values`; a value that is not a number, of
/// either sign, counts as +∞) and the bracket of its neighbours.
///
/// # Errors
/// [`Error::Numerical`] when no value is finite.
fn bracket(range: (f64, f64), grid: &[f64], values: &[f64]) -> Result<(usize, (f64, f64))> {
    let last = grid.len() - 1;
    // `total_cmp` puts a NaN with its sign bit set (as 0·∞ makes on x86-64) below every
    // number: it would be taken for the best point.
    let key = |i: usize| if values[i].is_nan() { f64::INFINITY } else { values[i] };
    let i = (0..grid.len()).min_by(|&a, &b| key(a).total_cmp(&key(b))).unwrap_or(0);
    if !values[i].is_finite() {
        return Err(Error::Numerical {
            context: "nuisance search".into(),
            reason: format!("no value in [{:.3e}, {:.3e}] gives a converged fit", range.0, range.1),
        });
    }
    Ok((i, (grid[i.saturating_sub(1)], grid[(i + 1).min(last)])))
}

/// Brent's absolute tolerance on the searched coordinate (the logarithm, for a log
/// search): his method stops within about 3 of it of the minimum (3e-5 in the logarithm is
/// 0.003 % of the loop's bandwidth; a noise-free log's one-step loss doubles some 3 % away,
/// so by 1e-6 of itself there).
const BRENT_TOLERANCE: f64 = 1e-5;

/// A scan and Brent's refinement ([`brent_search`], [`walk_search`]): the point found and
/// its loss, and the points scanned with their losses (in the searched range's own unit;
/// every grid point of a whole scan, the visited ones of a walk).
pub(crate) struct Searched {
    pub best: f64,
    pub loss: f64,
    pub scan: Vec<(f64, f64)>,
}

/// A scan of `points` evenly spaced points (on the logarithm when `log`), then Brent's
/// method on the bracket around its best point (argmin's `BrentOpt`, to
/// [`BRENT_TOLERANCE`]): some 10 evaluations where [`golden_search`]'s sections take 26.
/// The scan's best point is kept if Brent's is no lower.
///
/// # Errors
/// Those of `loss`; [`Error::Numerical`] when no scanned value is finite.
pub(crate) fn brent_search(
    range: (f64, f64),
    log: bool,
    points: usize,
    loss: impl Fn(f64) -> Result<f64>,
) -> Result<Searched> {
    let (to, from) = maps(log);
    let grid = grid(to(range.0), to(range.1), points.max(2));
    let values = grid.iter().map(|&x| loss(from(x))).collect::<Result<Vec<f64>>>()?;
    let visited = vec![true; grid.len()];
    refine(range, log, &grid, &values, &visited, loss)
}

/// [`brent_search`]'s scan walked from the grid point nearest `near` (in `range`'s own
/// unit) instead of taken whole: each way until a point is higher than its neighbour
/// before it and lies outside `within(value, lowest so far)`, so every point `within` the
/// lowest that joins it through points `within` is visited, and the best point's
/// neighbours with it. `within(v, b)` must keep no `v` for a lower `b` that it rejects for
/// a higher one (a likelihood-ratio bound does not), so that a point left outside stays
/// outside at the final lowest. On a loss with one basin along the grid (flat or not) the
/// best grid point, hence Brent's bracket and result, and the visited points `within` are
/// those of the whole scan; a loss with another basin beyond a rise outside `within` keeps
/// the basin it starts in. The scan returned holds the visited points only. The whole scan
/// is taken when `near` is not a number inside `range`, or when no visited value is
/// finite before the walk has seen every point.
///
/// # Errors
/// As [`brent_search`].
pub(crate) fn walk_search(
    range: (f64, f64),
    log: bool,
    points: usize,
    near: f64,
    within: impl Fn(f64, f64) -> bool,
    loss: impl Fn(f64) -> Result<f64>,
) -> Result<Searched> {
    let (to, from) = maps(log);
    let grid = grid(to(range.0), to(range.1), points.max(2));
    let at = to(near);
    if !(at > grid[0] && at < grid[grid.len() - 1]) {
        return brent_search(range, log, points, loss);
    }
    let start =
        (0..grid.len()).min_by(|&a, &b| (grid[a] - at).abs().total_cmp(&(grid[b] - at).abs())).unwrap_or(0);
    let mut values = vec![f64::INFINITY; grid.len()];
    let mut visited = vec![false; grid.len()];
    values[start] = loss(from(grid[start]))?;
    visited[start] = true;
    let mut best = values[start];
    for step in [-1isize, 1] {
        let mut j = start;
        while let Some(next) = j.checked_add_signed(step).filter(|&n| n < grid.len()) {
            values[next] = loss(from(grid[next]))?;
            visited[next] = true;
            best = best.min(values[next]);
            // A value that is not a number rises.
            let rises =
                matches!(values[next].partial_cmp(&values[j]), Some(std::cmp::Ordering::Greater) | None);
            j = next;
            if rises && !within(values[next], best) {
                break;
            }
        }
    }
    if !best.is_finite() && !visited.iter().all(|&v| v) {
        return brent_search(range, log, points, loss);
    }
    refine(range, log, &grid, &values, &visited, loss)
}

/// A map between a searched value and its coordinate.
type Map = fn(f64) -> f64;

/// The map to the searched coordinate and back: the logarithm and the exponential for a
/// log search, else the identity.
fn maps(log: bool) -> (Map, Map) {
    if log { (f64::ln, f64::exp) } else { (|x| x, |x| x) }
}

/// Brent's method on the bracket around the best of the scanned `values` at `grid` (in
/// the searched coordinate), the scan's best kept if Brent's is no lower; the scan reported
/// is the `visited` points.
///
/// # Errors
/// Those of `loss`; [`Error::Numerical`] when no scanned value is finite.
fn refine(
    range: (f64, f64),
    log: bool,
    grid: &[f64],
    values: &[f64],
    visited: &[bool],
    loss: impl Fn(f64) -> Result<f64>,
) -> Result<Searched> {
    use argmin::core::{CostFunction, Executor, State};
    struct Cost<F>(F);
    impl<F: Fn(f64) -> Result<f64>> CostFunction for Cost<F> {
        type Param = f64;
        type Output = f64;
        fn cost(&self, x: &f64) -> std::result::Result<f64, argmin::core::Error> {
            Ok((self.0)(*x)?)
        }
    }
    let from = maps(log).1;
    let (i, (a, b)) = bracket(range, grid, values)?;
    let solver =
        argmin::solver::brent::BrentOpt::new(a, b).set_tolerance(f64::EPSILON.sqrt(), BRENT_TOLERANCE);
    let res = Executor::new(Cost(move |x: f64| loss(from(x))), solver)
        .configure(|s| s.max_iters(100))
        .run()
        .map_err(Error::from_argmin)?;
    let (best, value) = match (res.state.get_best_param(), res.state.get_best_cost()) {
        (Some(&x), c) if c < values[i] => (x, c),
        _ => (grid[i], values[i]),
    };
    let scan =
        grid.iter().zip(values).zip(visited).filter(|(_, v)| **v).map(|((&x, &v), _)| (from(x), v)).collect();
    Ok(Searched { best: from(best), loss: value, scan })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brent's method finds a smooth minimum on the logarithm to its tolerance in fewer
    /// evaluations than the golden sections, and a scan of 25 returns its points.
    #[test]
    fn brent_finds_the_minimum_in_few_evaluations() {
        let count = std::cell::Cell::new(0);
        let loss = |a: f64| {
            count.set(count.get() + 1);
            let x = (a / 2224.0).ln();
            Ok(1.0 + x * x * (1.0 + 0.1 * x))
        };
        let found = brent_search(SPEED_PLL_RANGE, true, 25, loss).unwrap();
        assert!((found.best / 2224.0).ln().abs() < 3.0 * BRENT_TOLERANCE, "{}", found.best);
        assert_eq!(found.scan.len(), 25);
        assert!(
            (found.scan[0].0 - SPEED_PLL_RANGE.0).abs() < 1e-9
                && (found.scan[24].0 - SPEED_PLL_RANGE.1).abs() < 1e-6
        );
        let brent = count.get() - 25;
        assert!(brent < 26, "{brent} evaluations after the scan");
        let golden = std::cell::Cell::new(0);
        let best = golden_search(SPEED_PLL_RANGE, true, |a| {
            golden.set(golden.get() + 1);
            loss(a)
        })
        .unwrap();
        assert!((best / found.best).ln().abs() < 1e-4, "{best} against {}", found.best);
    }

    /// The walked scan finds what the whole scan finds on one basin, sharp (3 points of 25
    /// then Brent's) or flat (every point within the bound visited, none beyond the first
    /// rising outside it), and from a start on either side of the minimum.
    #[test]
    fn the_walk_finds_the_whole_scans_minimum_and_set_in_fewer_points() {
        let within = |v: f64, best: f64| v - best < 0.05;
        for (width, near) in [(0.03, 2000.0), (0.03, 2600.0), (2.0, 150.0), (2.0, 9000.0)] {
            let loss = |a: f64| Ok(1.0 + ((a / 2224.0).ln() / width).powi(2));
            let whole = brent_search(SPEED_PLL_RANGE, true, 25, loss).unwrap();
            let count = std::cell::Cell::new(0);
            let walked = walk_search(SPEED_PLL_RANGE, true, 25, near, within, |a| {
                count.set(count.get() + 1);
                loss(a)
            })
            .unwrap();
            // The same grid point, so the same bracket and Brent steps: equal to the bit.
            assert_eq!(walked.best, whole.best, "width {width} from {near}");
            let kept = |s: &Searched| -> Vec<(f64, f64)> {
                s.scan.iter().copied().filter(|&(_, v)| within(v, s.loss)).collect()
            };
            assert_eq!(kept(&walked), kept(&whole), "width {width} from {near}");
            assert!(walked.scan.len() < 25, "{} points", walked.scan.len());
            if width < 1.0 && (near / 2224.0).ln().abs() < 0.2 {
                assert!(walked.scan.len() <= 4, "{} points", walked.scan.len());
            }
            assert!(count.get() < 25 + 10, "{} evaluations", count.get());
        }
        // A start outside the range's interior takes the whole scan.
        let loss = |a: f64| Ok((a / 2224.0).ln().powi(2));
        let edge = walk_search(SPEED_PLL_RANGE, true, 25, f64::NAN, within, loss).unwrap();
        assert_eq!(edge.scan.len(), 25);
    }

    /// A failing loss inside Brent's steps is the loss's own error, not a solver's string;
    /// a scan with no finite value is a numerical error.
    #[test]
    fn brent_passes_the_loss_errors_on() {
        let failing = |a: f64| {
            if (a / 2224.0).ln().abs() < 0.1 {
                Err(Error::InvalidOption { option: "speed_pll".into(), reason: "test".into() })
            } else {
                Ok((a / 2224.0).ln().powi(2))
            }
        };
        match brent_search(SPEED_PLL_RANGE, true, 16, failing) {
            Err(Error::InvalidOption { option, .. }) => assert_eq!(option, "speed_pll"),
            other => panic!("{:?}", other.map(|s| s.best)),
        }
        let nan = brent_search(SPEED_PLL_RANGE, true, 16, |_| Ok(f64::NAN));
        assert!(matches!(nan, Err(Error::Numerical { .. })), "{:?}", nan.map(|s| s.best));
        // A NaN with its sign bit set at one point is not taken for the best: the finite
        // minimum is found by the whole scan and by the walk.
        let negative_nan = -f64::NAN;
        assert!(negative_nan.is_sign_negative());
        let holed = |a: f64| {
            let x = (a / 2224.0).ln();
            Ok(if x < -3.0 { negative_nan } else { 1.0 + x * x })
        };
        let whole = brent_search(SPEED_PLL_RANGE, true, 25, holed).unwrap();
        assert!((whole.best / 2224.0).ln().abs() < 1e-3, "{}", whole.best);
        let walked = walk_search(SPEED_PLL_RANGE, true, 25, 100.0, |v, b| v - b < 0.05, holed).unwrap();
        assert_eq!(walked.best, whole.best);
    }
}
