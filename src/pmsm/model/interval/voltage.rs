//! The voltage of a model's intervals as its data hold it: the log's own terminal-voltage
//! channels (shared with the experiment, not copied) or the start-of-period voltages a
//! reference input is turned into. The start-of-period voltage of a stator-held terminal
//! voltage follows per interval (MODEL.md §4).

use super::{C64, VoltageHold, stator_hold_start_half};
use crate::data::Values;

/// The voltage that drives a PMSM model's intervals \[V\]: the terminal voltage's two
/// channels of length N, or N − 1 start-of-period voltages.
#[derive(Clone, Debug)]
pub enum IntervalVoltage {
    /// The measured terminal voltage `(u_d, u_q)`, period means \[V\], length N each (the
    /// experiment's channels, shared).
    Terminal(Values, Values),
    /// The dq voltage at the start of each period `u₀` \[V\], length N − 1 (the reference
    /// voltage, delayed and advanced: [`crate::pmsm::model_intervals`]).
    Start(Vec<C64>),
}

impl IntervalVoltage {
    /// The dq voltage at the start of interval k \[V\] for the `hold`, from the interval's
    /// angle `φ = ω_e h` \[rad\] and `(s, c) = (sin φ/2, cos φ/2)`: `u[k]` (dq hold) or
    /// `u₀ = u[k] jφ/(1 − e^{−jφ})` (stator hold) of the terminal voltage, the stored `u₀`
    /// of a reference.
    ///
    /// # Panics
    /// If k is past the data (k ≥ N − 1 for [`Start`](Self::Start), k ≥ N otherwise).
    #[inline(always)]
    pub fn start(&self, hold: VoltageHold, k: usize, phi: f64, s: f64, c: f64) -> C64 {
        let stator = hold == VoltageHold::Stator;
        match self {
            Self::Terminal(d, q) => terminal_start(stator, C64::new(d[k], q[k]), phi, s, c),
            Self::Start(u0) => u0[k],
        }
    }
}

/// The start-of-period dq voltage of the terminal voltage `uk` (the period mean) over an
/// interval of angle `phi` and half angle `(s, c)`: `uk` itself for the dq hold.
#[inline(always)]
pub(crate) fn terminal_start(stator: bool, uk: C64, phi: f64, s: f64, c: f64) -> C64 {
    if stator { stator_hold_start_half(uk, phi, s, c) } else { uk }
}
