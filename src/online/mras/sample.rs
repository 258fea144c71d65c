//! One sample of a drive, what the observer reads.

use serde::{Deserialize, Serialize};

/// One sample of a drive: the currents measured at `t_k` and the voltage applied over
/// the coming period `[t_k, t_k + h)` (MODEL.md §4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// d-axis current at `t_k` \[A, peak dq\].
    pub i_d: f64,
    /// q-axis current at `t_k` \[A, peak dq\].
    pub i_q: f64,
    /// d-axis voltage over `[t_k, t_k + h)` \[V\], its period mean.
    pub u_d: f64,
    /// q-axis voltage over `[t_k, t_k + h)` \[V\], its period mean.
    pub u_q: f64,
    /// Mechanical speed over the coming period \[rad/s\] (the interval mean
    /// `(ω_m[k] + ω_m[k+1])/2` when known, as [`crate::online::track()`] passes it; else ω_m\[k\]).
    pub w_m: f64,
}
