//! The intervals of a log as arrays, one per quantity (structure of arrays): what the
//! models' `prepare` keeps. For the terminal voltage each array is computed in its own
//! loop over independent intervals (they vectorise), with one sine and cosine of the half
//! angle per interval (MODEL.md §4; thesis 5.2); the numbers are those of
//! [`intervals`](super::intervals).

use super::{
    C64, DqView, Interval, Result, SQRT_2_3, VoltageHold, VoltageInput, half_angle, half_angle_rotation,
    mean_speed, model_intervals, stator_hold_start_half,
};

/// The intervals `k = 0..N−2` of a log (see [`Interval`]), each field an array of N − 1.
#[derive(Clone, Debug, Default)]
pub(crate) struct IntervalArrays {
    /// Interval-mean electrical speed ω_e \[rad/s\].
    pub w_e: Vec<f64>,
    /// `√(2/3)` × interval-mean mechanical speed \[rad/s\].
    pub emf: Vec<f64>,
    /// `e^{−jφ}`, `φ = ω_e h`.
    pub rot: Vec<C64>,
    /// `1 − cos φ`.
    pub vers: Vec<f64>,
    /// dq voltage at the start of the period \[V\].
    pub u0: Vec<C64>,
}

/// The intervals of [`model_intervals`] as arrays.
///
/// # Errors
/// Those of [`model_intervals`].
pub(crate) fn model_interval_arrays(
    v: &DqView<'_>,
    n_p: u32,
    hold: VoltageHold,
    input: VoltageInput,
) -> Result<IntervalArrays> {
    if input != VoltageInput::Terminal {
        let ivs = model_intervals(v, n_p, hold, input)?;
        let field = |f: fn(&Interval) -> f64| ivs.iter().map(f).collect();
        return Ok(IntervalArrays {
            w_e: field(|iv| iv.w_e),
            emf: field(|iv| iv.emf),
            vers: field(|iv| iv.vers),
            rot: ivs.iter().map(|iv| iv.rot).collect(),
            u0: ivs.iter().map(|iv| iv.u0).collect(),
        });
    }
    let (ud, uq) = v.terminal_voltage()?;
    let (h, np, wm) = (v.h(), f64::from(n_p), v.w_m());
    let n = v.len() - 1;
    let w_e: Vec<f64> = wm.windows(2).map(|w| np * mean_speed(w)).collect();
    let emf: Vec<f64> = wm.windows(2).map(|w| SQRT_2_3 * mean_speed(w)).collect();
    // (sin φ/2, cos φ/2) held in `rot` until the other arrays have taken them.
    let mut rot: Vec<C64> = w_e
        .iter()
        .map(|&w| {
            let (s, c) = half_angle(w, h);
            C64::new(s, c)
        })
        .collect();
    let mean = |k: usize| C64::new(ud[k], uq[k]);
    let u0: Vec<C64> = match hold {
        VoltageHold::Dq => (0..n).map(mean).collect(),
        VoltageHold::Stator => {
            (0..n).map(|k| stator_hold_start_half(mean(k), w_e[k] * h, rot[k].re, rot[k].im)).collect()
        }
    };
    let mut vers = Vec::with_capacity(n);
    for r in &mut rot {
        let (turn, vs) = half_angle_rotation(r.re, r.im);
        *r = turn;
        vers.push(vs);
    }
    Ok(IntervalArrays { w_e, emf, rot, vers, u0 })
}
