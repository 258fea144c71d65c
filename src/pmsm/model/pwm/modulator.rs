//! The modulator and the carrier comparison, on the data alone: from each period's voltage
//! reference the duty ratios of the three legs and, per half carrier period, each leg's
//! switching instant and commanded state (the plan the switching-resolved step follows).
//!
//! Space-vector PWM as min-max zero sequence (Holmes & Lipo, *Pulse Width Modulation for
//! Power Converters*, 2003, §6.5: the min-max injection equals the symmetric space-vector
//! modulator), or sinusoidal PWM (no zero sequence); overmodulation by the minimum phase
//! error (the magnitude scaled back to the hexagon's inscribed circle where a leg would
//! leave `[0, 1]`), then each duty clipped to `[0, 1]`. The carrier is a triangle whose
//! peaks and valleys are the sampling instants (double update: one half carrier period per
//! sample, alternately rising and falling; single update: a whole carrier period per
//! sample). A rising half turns each switching leg on at `T (1 − d)`, a falling half off at
//! `T d`; a leg at duty 0 or 1 does not switch. This is the carrier comparison of
//! motulator's `CarrierComparison` (Hinkkanen et al., Aalto University), whose semantics of
//! a blanking interval carried over a half-period boundary are kept.

use super::{Modulator, PwmInverter, PwmUpdate};

/// One half carrier period of one leg set: what the data decide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct HalfPlan {
    /// Start within the sample period \[s\].
    pub offset: f64,
    /// Length T \[s\].
    pub len: f64,
    /// Each leg's switching instant from the half's start \[s\]; ∞ for a leg that does not
    /// switch.
    pub t_sw: [f64; 3],
    /// Each leg's commanded state before its switching instant (true: upper switch on).
    pub cmd: [bool; 3],
    /// Whether the command differs from the state the previous half left (a turn-on at
    /// the half's start, blanked for the dead time).
    pub changed: [bool; 3],
    /// The previous half's switching instant minus its length \[s\] (≤ 0), for a blanking
    /// interval that runs on into this half; −∞ when that leg did not switch.
    pub carry: [f64; 3],
}

/// The duty ratios `d_a, d_b, d_c` in `[0, 1]` of the stator voltage reference `(α, β)`
/// \[V\] at DC-link voltage `u_dc` \[V\] for the inverter's modulator, quantised to its
/// counter's levels if it has them (round half to even, as a counter compare register).
pub(crate) fn duty_ratios(inv: &PwmInverter, alpha: f64, beta: f64, u_dc: f64) -> [f64; 3] {
    let (a, b, c) = crate::pmsm::log::transform::inverse_clarke(alpha, beta);
    let mut u = [a, b, c];
    if inv.modulator == Modulator::MinMax {
        let (hi, lo) = u.iter().fold((f64::NEG_INFINITY, f64::INFINITY), |(h, l), &x| (h.max(x), l.min(x)));
        let u0 = 0.5 * (hi + lo);
        u = u.map(|x| x - u0);
        // Minimum phase error: the vector scaled back onto the hexagon.
        let m = 2.0 / u_dc * u.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if m > 1.0 {
            u = u.map(|x| x / m);
        }
    }
    u.map(|x| {
        let d = (x / u_dc + 0.5).clamp(0.0, 1.0);
        match inv.levels {
            Some(n) if n > 0 => (f64::from(n) * d).round_ties_even() / f64::from(n),
            _ => d,
        }
    })
}

/// The carrier's state between half periods: each leg's last command and the switching
/// instant that may still be blanking.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Carrier {
    /// Each leg's state after the last half (`None` before the first).
    last: Option<[bool; 3]>,
    carry: [f64; 3],
}

impl Carrier {
    /// The plan of the next half period of length `len` \[s\] starting `offset` \[s\] into
    /// its sample period, rising or falling, for the duty ratios `d`.
    pub(crate) fn half(&mut self, d: [f64; 3], rising: bool, offset: f64, len: f64) -> HalfPlan {
        let cmd = d.map(|d| if rising { d == 1.0 } else { d > 0.0 });
        let t_sw: [f64; 3] = std::array::from_fn(|x| {
            let t = if rising { len * (1.0 - d[x]) } else { len * d[x] };
            if d[x] > 0.0 && d[x] < 1.0 { t } else { f64::INFINITY }
        });
        let last = self.last.unwrap_or(cmd);
        let changed = std::array::from_fn(|x| cmd[x] != last[x]);
        let plan = HalfPlan {
            offset,
            len,
            t_sw,
            cmd,
            changed,
            carry: if self.last.is_some() { self.carry } else { [f64::NEG_INFINITY; 3] },
        };
        self.last = Some(std::array::from_fn(|x| if t_sw[x] < len { !cmd[x] } else { cmd[x] }));
        self.carry = std::array::from_fn(|x| if t_sw[x] < len { t_sw[x] - len } else { f64::NEG_INFINITY });
        plan
    }
}

/// The half periods of one sample period of length `h` \[s\]: one (double update) or two
/// (single update); the first rising when `rising`.
pub(crate) fn halves(
    inv: &PwmInverter,
    carrier: &mut Carrier,
    d: [f64; 3],
    rising: bool,
    h: f64,
) -> ([HalfPlan; 2], usize) {
    match inv.update {
        PwmUpdate::Double => {
            let a = carrier.half(d, rising, 0.0, h);
            ([a, a], 1)
        }
        PwmUpdate::Single => {
            let a = carrier.half(d, rising, 0.0, 0.5 * h);
            let b = carrier.half(d, !rising, 0.5 * h, 0.5 * h);
            ([a, b], 2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// motulator's `CarrierComparison` docstring example: duty ratios (0.4, 0.2, 0.8) over
    /// a 1 ms half period rise at 0.6, 0.8 and 0.2 ms, then fall at 0.4, 0.2 and 0.8 ms;
    /// with a 0.1 ms dead time at duty 0.5 the second half starts with its legs changed.
    #[test]
    fn the_carrier_switches_where_motulator_does() {
        let mut c = Carrier::default();
        let d = [0.4, 0.2, 0.8];
        let up = c.half(d, true, 0.0, 1e-3);
        assert_eq!(up.cmd, [false; 3]);
        for (t, want) in up.t_sw.iter().zip([0.6e-3, 0.8e-3, 0.2e-3]) {
            assert!((t - want).abs() < 1e-15);
        }
        assert_eq!(up.changed, [false; 3]);
        let down = c.half(d, false, 0.0, 1e-3);
        assert_eq!(down.cmd, [true; 3]);
        assert_eq!(down.changed, [false; 3], "the rising half left every leg on");
        for (t, want) in down.t_sw.iter().zip([0.4e-3, 0.2e-3, 0.8e-3]) {
            assert!((t - want).abs() < 1e-15);
        }
        for (carry, t_sw) in down.carry.iter().zip(up.t_sw) {
            assert!((carry - (t_sw - 1e-3)).abs() < 1e-18);
        }
        // A leg at duty 1 during a falling half stays on and does not switch.
        let clamp = Carrier::default().half([1.0, 0.0, 0.5], false, 0.0, 1e-3);
        assert_eq!(clamp.t_sw[0], f64::INFINITY);
        assert_eq!(clamp.t_sw[1], f64::INFINITY);
        assert_eq!(clamp.cmd, [true, false, true]);
    }

    /// Min-max duty ratios centre the three legs on one half; the sine modulator does not
    /// shift them; counter levels round to the grid.
    #[test]
    fn the_modulators_duty_ratios() {
        let mut inv = PwmInverter::default();
        let d = duty_ratios(&inv, 100.0, 40.0, 400.0);
        let (hi, lo) = (d.iter().copied().fold(0.0, f64::max), d.iter().copied().fold(1.0, f64::min));
        assert!((hi + lo - 1.0).abs() < 1e-15, "{d:?}");
        inv.modulator = Modulator::Sine;
        let s = duty_ratios(&inv, 100.0, 40.0, 400.0);
        assert!((s.iter().sum::<f64>() - 1.5).abs() < 1e-15, "{s:?}");
        inv.levels = Some(16);
        for x in duty_ratios(&inv, 100.0, 40.0, 400.0) {
            assert_eq!((x * 16.0).fract(), 0.0);
        }
    }
}
