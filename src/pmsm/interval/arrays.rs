//! The intervals of a log as arrays, one per quantity (structure of arrays): what the
//! IPM model's `prepare` keeps. For the terminal voltage each array is computed in its own
//! loop over independent intervals (they vectorise), the stator hold's start voltage with
//! one sine and cosine of the half angle per interval (MODEL.md §4; thesis 5.2); the
//! numbers are those of [`intervals`](super::intervals).

use super::{
    C64, DqView, Result, SQRT_2_3, VoltageHold, VoltageInput, half_angle, mean_speed, model_start_voltages,
    stator_hold_start_half,
};
#[cfg(doc)]
use super::{Interval, model_intervals};

/// The intervals `k = 0..N−2` of a log (see [`Interval`]), each field an array of N − 1:
/// the few numbers from which every data-only term of an interval follows exactly (24
/// bytes an interval), so the prepared inputs stay small.
#[derive(Clone, Debug, Default)]
pub(crate) struct IntervalArrays {
    /// Interval-mean mechanical speed ω_m \[rad/s\]: `ω_e = n_p ω_m`, back-EMF per unit K_e
    /// `√(2/3) ω_m`.
    pub w_m: Vec<f64>,
    /// dq voltage at the start of the period \[V\].
    pub u0: Vec<C64>,
}

impl IntervalArrays {
    /// `(ω_e, √(2/3) ω_m)` of every interval for `n_p` pole pairs \[rad/s\]: the numbers of
    /// [`Interval`]'s `w_e` and `emf`.
    pub(crate) fn speeds(&self, n_p: u32) -> (Vec<f64>, Vec<f64>) {
        let np = f64::from(n_p);
        (self.w_m.iter().map(|w| np * w).collect(), self.w_m.iter().map(|w| SQRT_2_3 * w).collect())
    }
}

/// The intervals of [`model_intervals`] as arrays (the same numbers: every field of an
/// [`Interval`] follows from them by the same operations).
///
/// # Errors
/// Those of [`model_intervals`].
pub(crate) fn model_interval_arrays(
    v: &DqView<'_>,
    n_p: u32,
    hold: VoltageHold,
    input: VoltageInput,
) -> Result<IntervalArrays> {
    let (h, np) = (v.h(), f64::from(n_p));
    let w_m: Vec<f64> = v.w_m().windows(2).map(mean_speed).collect();
    if input != VoltageInput::Terminal {
        let u0 = model_start_voltages(v, n_p, hold, input)?;
        return Ok(IntervalArrays { w_m, u0 });
    }
    let (ud, uq) = v.terminal_voltage()?;
    let mean = |k: usize| C64::new(ud[k], uq[k]);
    let u0: Vec<C64> = match hold {
        VoltageHold::Dq => (0..w_m.len()).map(mean).collect(),
        VoltageHold::Stator => w_m
            .iter()
            .enumerate()
            .map(|(k, &w)| {
                let (s, c) = half_angle(np * w, h);
                stator_hold_start_half(mean(k), np * w * h, s, c)
            })
            .collect(),
    };
    Ok(IntervalArrays { w_m, u0 })
}
