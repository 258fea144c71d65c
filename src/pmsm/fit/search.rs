//! Searches of one nuisance value by whole fits or one-step losses: a scan, then a
//! golden-section search on the bracket around its best point (Kiefer, *Proc. AMS* 4 (1953)
//! 502–506), and the range of the controller's phase-locked loop that the voltage input's
//! and the PWM fit's searches share.

use crate::error::{Error, Result};

/// Range of the speed-estimator bandwidth searched \[rad/s\]: 2π·10 Hz to 2π·2 kHz.
pub const SPEED_PLL_RANGE: (f64, f64) = (62.83185307179586, 12_566.370614359172);
/// Log-spaced bandwidths of the coarse scan before the golden-section refinement.
const COARSE: usize = 16;
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
    type Map = fn(f64) -> f64;
    let (to, from): (Map, Map) = if log { (f64::ln, f64::exp) } else { (|x| x, |x| x) };
    let mut loss = move |x: f64| loss(from(x));
    let (lo, hi) = (to(range.0), to(range.1));
    let grid: Vec<f64> = (0..COARSE).map(|i| lo + (hi - lo) * i as f64 / (COARSE - 1) as f64).collect();
    let mut values = Vec::with_capacity(COARSE);
    for &x in &grid {
        values.push(loss(x)?);
    }
    let i = (0..COARSE).min_by(|&a, &b| values[a].total_cmp(&values[b])).unwrap_or(0);
    if !values[i].is_finite() {
        return Err(Error::Numerical {
            context: "nuisance search".into(),
            reason: format!("no value in [{:.3e}, {:.3e}] gives a converged fit", range.0, range.1),
        });
    }
    let (mut a, mut b) = (grid[i.saturating_sub(1)], grid[(i + 1).min(COARSE - 1)]);
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
