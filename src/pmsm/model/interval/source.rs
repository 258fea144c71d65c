//! The data a PMSM model's intervals are formed from, independent of θ: the log's speed
//! and voltage channels, shared with the experiment (not copied), with the sample time and
//! pole pairs; each interval's mean speed, half-angle sine and cosine and start-of-period
//! voltage follow from them per interval or per block (MODEL.md §4). Both
//! [`SpmInputs`](crate::pmsm::SpmInputs) and [`IpmInputs`](crate::pmsm::model::augmented::IpmInputs) hold one.

use super::{
    C64, IntervalVoltage, SMALL_ANGLE, SQRT_2_3, VoltageHold, VoltageInput, half_angle, half_angle_arg,
    half_angle_rotation, mean_speed, model_start_voltages, sin_cos_small, terminal_start,
};
use crate::data::Values;
use crate::error::Result;
use crate::pmsm::log::signals::DqView;

/// The θ-independent data of a PMSM model's intervals (interval k runs from sample k to
/// k + 1, k = 0..N−2).
#[derive(Clone, Debug)]
pub struct IntervalSource {
    /// Sample time h \[s\].
    pub h: f64,
    /// Pole pairs n_p as a number: `ω_e = n_p ω_m` (the model's, set by `prepare`).
    pub n_p: f64,
    /// Mechanical speed at the samples ω_m \[rad/s\], length N (the experiment's channel);
    /// interval k runs at the mean `(ω_m[k] + ω_m[k+1])/2`.
    pub w_m: Values,
    /// The voltage that drives the step \[V\] (terminal channels of length N, or N − 1
    /// start-of-period voltages).
    pub u: IntervalVoltage,
}

/// Arrays of equal length a block of intervals' data is formed in (structure of arrays):
/// mean speed ω_m \[rad/s\], `sin φ/2`, `cos φ/2`, and the voltage term's real and
/// imaginary parts \[V\] ([`IntervalSource::interval`]).
pub(crate) struct IntervalData<'a> {
    pub w_m: &'a mut [f64],
    pub sin: &'a mut [f64],
    pub cos: &'a mut [f64],
    pub u_re: &'a mut [f64],
    pub u_im: &'a mut [f64],
}

impl IntervalSource {
    /// The source of a log for a model of `n_p` pole pairs with the voltage `hold`, driven
    /// by `input`: the log's speed channel and, for the terminal voltage, its voltage
    /// channels, shared (not copied); for a reference, its start-of-period voltages
    /// ([`model_start_voltages`]: 16 bytes an interval).
    ///
    /// # Errors
    /// [`crate::Error::MissingChannel`] for a voltage channel the input needs; those of
    /// [`model_start_voltages`] for a reference.
    pub(crate) fn of_log(v: &DqView<'_>, n_p: u32, hold: VoltageHold, input: VoltageInput) -> Result<Self> {
        let u = match input {
            VoltageInput::Terminal => {
                let (d, q) = v.shared_terminal_voltage()?;
                IntervalVoltage::Terminal(d.clone(), q.clone())
            }
            VoltageInput::Reference { .. } => {
                IntervalVoltage::Start(model_start_voltages(v, n_p, hold, input)?)
            }
        };
        Ok(Self { h: v.h(), n_p: f64::from(n_p), w_m: v.shared_w_m().clone(), u })
    }

    /// One interval at rest with a zero start-of-period voltage, for a plant that sets it
    /// every step ([`set_one`](Self::set_one)).
    pub(crate) fn one(h: f64, n_p: f64) -> Self {
        Self { h, n_p, w_m: vec![0.0; 2].into(), u: IntervalVoltage::Start(vec![C64::default()]) }
    }

    /// Sets the one interval of a plant's source: mean speed `w` \[rad/s\] (both ends at
    /// `w`, so `(w + w)/2 = w` exactly) and start-of-period dq voltage `u0` \[V\]. Allocates
    /// nothing once the data are of that shape (as [`one`](Self::one) makes them).
    pub(crate) fn set_one(&mut self, w: f64, u0: C64) {
        std::sync::Arc::make_mut(&mut self.w_m).fill(w);
        match &mut self.u {
            IntervalVoltage::Start(v) if !v.is_empty() => v[0] = u0,
            other => *other = IntervalVoltage::Start(vec![u0]),
        }
    }

    /// Whether the source holds the data of a record of `n` samples: at least n speeds and,
    /// for the terminal voltage, n samples of each channel, for start voltages n − 1 (what
    /// the per-interval methods index for the intervals `0..n − 1`).
    pub fn covers(&self, n: usize) -> bool {
        let u = match &self.u {
            IntervalVoltage::Terminal(d, q) => d.len().min(q.len()) >= n,
            IntervalVoltage::Start(u0) => u0.len() + 1 >= n,
        };
        self.w_m.len() >= n && u
    }

    /// Number of intervals N − 1.
    pub fn intervals(&self) -> usize {
        self.w_m.len().saturating_sub(1)
    }

    /// Interval k's electrical speed ω_e and back-EMF per unit K_e `√(2/3) ω_m` \[rad/s\],
    /// at its mean speed.
    ///
    /// # Panics
    /// If k ≥ N − 1.
    #[inline]
    pub fn speeds(&self, k: usize) -> (f64, f64) {
        let w = mean_speed(&self.w_m[k..k + 2]);
        (self.n_p * w, SQRT_2_3 * w)
    }

    /// `(sin φ/2, cos φ/2)` of interval k's rotation `φ = ω_e h` at its mean speed.
    ///
    /// # Panics
    /// If k ≥ N − 1.
    #[inline]
    pub fn half_angle(&self, k: usize) -> (f64, f64) {
        half_angle(self.n_p * mean_speed(&self.w_m[k..k + 2]), self.h)
    }

    /// Interval k's dq voltage at the start of the period \[V\] for the `hold`: `u[k]` (dq
    /// hold) or `u₀ = u[k] jφ/(1 − e^{−jφ})` (stator hold) of the terminal voltage, or a
    /// reference's.
    ///
    /// # Panics
    /// If k ≥ N − 1.
    #[inline]
    pub fn start_voltage(&self, hold: VoltageHold, k: usize) -> C64 {
        let w_e = self.speeds(k).0;
        let (s, c) = if hold == VoltageHold::Stator { half_angle(w_e, self.h) } else { (0.0, 1.0) };
        self.u.start(hold, k, w_e * self.h, s, c)
    }

    /// Interval k's data (`k < N − 1`) for the `hold`: `[sin φ/2, cos φ/2]` of its
    /// rotation `φ = ω_e h`, its mean mechanical speed ω_m \[rad/s\] and its voltage term
    /// \[V\]: `u[k]` (dq hold) or `u₀ e^{−jφ}` (stator hold, the start-of-period voltage seen
    /// at the period's end). The per-sample step and the block kernel both take their data
    /// from here, so they give the same numbers to the bit.
    ///
    /// # Panics
    /// If k ≥ N − 1.
    #[inline(always)]
    pub fn interval(&self, hold: VoltageHold, k: usize) -> ([f64; 2], f64, C64) {
        let w = mean_speed(&self.w_m[k..k + 2]);
        let (s, c) = half_angle(self.n_p * w, self.h);
        let u0 = self.u.start(hold, k, self.n_p * w * self.h, s, c);
        ([s, c], w, seen_at_end(hold == VoltageHold::Stator, u0, s, c))
    }

    /// [`interval`](Self::interval) for the intervals `k0 .. k0 + out.w_m.len()` into `out`
    /// (arrays of equal length), the same numbers to the bit: the loops run over independent
    /// intervals and vectorise.
    ///
    /// # Panics
    /// If the arrays of `out` differ in length, or the intervals run past N − 1.
    #[inline(always)]
    pub(crate) fn fill_intervals(&self, stator: bool, k0: usize, out: IntervalData<'_>) {
        let IntervalData { w_m, sin, cos, u_re, u_im } = out;
        let steps = w_m.len();
        for (w, pair) in w_m.iter_mut().zip(self.w_m[k0..k0 + steps + 1].windows(2)) {
            *w = mean_speed(pair);
        }
        // `half_angle` in two loops: the polynomial for every interval (vectorised), then,
        // where an interval's half angle passes π/4 (a quarter of the sample rate), the
        // library's sine, as `half_angle` has it. The half angle grows with |ω_m| (rounding
        // is monotone), so the largest speed tells whether any does.
        for ((s, c), &w) in sin.iter_mut().zip(cos.iter_mut()).zip(w_m.iter()) {
            (*s, *c) = sin_cos_small(half_angle_arg(self.n_p * w, self.h));
        }
        if half_angle_arg(self.n_p * largest_magnitude(w_m), self.h) > SMALL_ANGLE {
            for ((s, c), &w) in sin.iter_mut().zip(cos.iter_mut()).zip(w_m.iter()) {
                let x = half_angle_arg(self.n_p * w, self.h);
                if x.abs() > SMALL_ANGLE {
                    (*s, *c) = x.sin_cos();
                }
            }
        }
        // Every array cut to `steps`, so the loops below carry no bounds checks and vectorise.
        let (sin, cos, w_m) = (&sin[..steps], &cos[..steps], &w_m[..steps]);
        let (u_re, u_im) = (&mut u_re[..steps], &mut u_im[..steps]);
        let mut put = |t: usize, u: C64| {
            u_re[t] = u.re;
            u_im[t] = u.im;
        };
        match &self.u {
            IntervalVoltage::Terminal(d, q) => {
                let (d, q) = (&d[k0..k0 + steps], &q[k0..k0 + steps]);
                for t in 0..steps {
                    let (s, c) = (sin[t], cos[t]);
                    let u0 = terminal_start(stator, C64::new(d[t], q[t]), self.n_p * w_m[t] * self.h, s, c);
                    put(t, seen_at_end(stator, u0, s, c));
                }
            }
            IntervalVoltage::Start(u0) => {
                for (t, &u0) in u0[k0..k0 + steps].iter().enumerate() {
                    put(t, seen_at_end(stator, u0, sin[t], cos[t]));
                }
            }
        }
    }
}

/// `max_k |v_k|` (0 for none), in eight lanes so that it vectorises.
#[inline(always)]
fn largest_magnitude(v: &[f64]) -> f64 {
    let mut lanes = [0.0f64; 8];
    let chunks = v.chunks_exact(8);
    let rest = chunks.remainder();
    for c in chunks {
        for (m, x) in lanes.iter_mut().zip(c) {
            // A comparison rather than `f64::max`: it vectorises.
            *m = if x.abs() > *m { x.abs() } else { *m };
        }
    }
    rest.iter().chain(&lanes).fold(0.0, |m, x| if x.abs() > m { x.abs() } else { m })
}

/// The voltage term of the step from the start-of-period voltage `u0`: for the stator hold
/// turned by the period's rotation `e^{−jφ}` (from `(s, c) = (sin φ/2, cos φ/2)`), the
/// stator-held voltage seen at the period's end; the dq-held one as it is.
#[inline(always)]
fn seen_at_end(stator: bool, u0: C64, s: f64, c: f64) -> C64 {
    if stator { u0 * half_angle_rotation(s, c).0 } else { u0 }
}
