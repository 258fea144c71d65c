//! Digital Butterworth low-pass filter and its zero-phase (forward-backward) application.
//!
//! The thesis prefilters the data with a 4th-order low-pass (MODEL.md §5); for the linear
//! least squares every signal must see the *same* filter with *no* phase shift, or the
//! pairing of voltage and current step (MODEL.md §4) is lost. Hence:
//!
//! - **Design** ([`Butterworth::try_new`]): the analog Butterworth prototype of order n
//!   with poles `s_k = Ω_c e^{j(π/2 + (2k−1)π/(2n))}`, the cutoff pre-warped to
//!   `Ω_c = (2/h) tan(π f_c h)` and mapped by the bilinear transform
//!   `z = (1 + s h/2)/(1 − s h/2)` (Oppenheim & Schafer, *Discrete-Time Signal
//!   Processing*, 3rd ed., §7.1–7.2). Each conjugate pole pair becomes one second-order
//!   section (biquad) with the double zero at `z = −1`; the high-order polynomial is never
//!   formed. Sections are ordered by increasing pole radius, as `scipy.signal.butter(…,
//!   output='sos')` orders them, and each has unit DC gain.
//! - **Zero-phase application** ([`Butterworth::filtfilt`]): the record is extended at
//!   both ends by odd reflection (`2 x[0] − x[p−i]`), filtered forward with every section
//!   started in the steady state of a constant input equal to the first extended sample,
//!   then filtered backward the same way, and the extension is cut off. This is
//!   `scipy.signal.sosfiltfilt(…, padtype='odd')` with the per-section steady-state
//!   initial conditions of `sosfilt_zi`; the steady-state start removes the start-up
//!   transient for slowly varying edges (Gustafsson, "Determining the initial states in
//!   forward-backward filtering", IEEE Trans. Signal Processing 44(4), 1996). The
//!   magnitude response is `|H|²`, the phase is zero.

use crate::data::{Channel, Experiment};
use crate::error::{Error, Result};
use nalgebra::Complex;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Default filter order (the thesis' 4th-order low-pass).
pub const DEFAULT_ORDER: usize = 4;

/// Largest accepted filter order.
pub const MAX_ORDER: usize = 32;

/// Padding at each end, in time constants of the slowest pole, at least (see
/// [`Butterworth::pad_len`]).
pub const PAD_TIME_CONSTANTS: f64 = 10.0;

/// Checks a filter order: even, between 2 and [`MAX_ORDER`].
///
/// # Errors
/// [`Error::InvalidOption`] with option `order` otherwise.
pub fn check_order(order: usize) -> Result<()> {
    if order == 0 || order % 2 == 1 || order > MAX_ORDER {
        return Err(Error::InvalidOption {
            option: "order".into(),
            reason: format!(
                "Butterworth order must be even, between 2 and {MAX_ORDER} (second-order sections), got {order}"
            ),
        });
    }
    Ok(())
}

/// One second-order section `H(z) = (b0 + b1 z⁻¹ + b2 z⁻²)/(1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Biquad {
    /// Numerator `[b0, b1, b2]`.
    pub b: [f64; 3],
    /// Denominator `[1, a1, a2]` (normalised, `a[0] = 1`).
    pub a: [f64; 3],
}

impl Biquad {
    /// DC gain `H(1) = Σb/Σa` (dimensionless).
    pub fn dc_gain(&self) -> f64 {
        self.b.iter().sum::<f64>() / self.a.iter().sum::<f64>()
    }

    /// Transposed direct form II state `[z1, z2]` of this section in steady state under a
    /// constant input 1 (`scipy.signal.lfilter_zi` for a biquad).
    fn steady_state(&self) -> [f64; 2] {
        let g = self.dc_gain();
        let z2 = self.b[2] - self.a[2] * g;
        [self.b[1] - self.a[1] * g + z2, z2]
    }

    /// Response at `w = z⁻¹` (complex).
    fn response(&self, w: Complex<f64>) -> Complex<f64> {
        let num = Complex::new(self.b[0], 0.0) + w * (self.b[1] + w * self.b[2]);
        let den = Complex::new(self.a[0], 0.0) + w * (self.a[1] + w * self.a[2]);
        num / den
    }
}

/// A digital Butterworth low-pass of even order as cascaded biquads, for sample time h.
///
/// Construct with [`Butterworth::try_new`]; apply causally with [`Butterworth::filter`]
/// or with zero phase with [`Butterworth::filtfilt`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Butterworth {
    order: usize,
    cutoff: f64,
    h: f64,
    sections: Vec<Biquad>,
}

impl Butterworth {
    /// Designs the low-pass of `order` (even, 2..=[`MAX_ORDER`]) with cutoff `cutoff` \[Hz\]
    /// (the −3 dB frequency of one pass) for sample time `h` \[s\].
    ///
    /// # Errors
    /// [`Error::InvalidSampleTime`] for `h` not positive and finite;
    /// [`Error::InvalidOption`] with option `order` for an order that is 0, odd or above
    /// [`MAX_ORDER`], and with option `cutoff` for a cutoff outside `(0, 1/(2h))` (the
    /// Nyquist frequency) or not finite.
    ///
    /// # Source
    /// Bilinear transform with pre-warping (Oppenheim & Schafer, 3rd ed., §7.1.2, §7.2);
    /// the numbers agree with `scipy.signal.butter(order, 2 cutoff h, output='sos')`.
    pub fn try_new(order: usize, cutoff: f64, h: f64) -> Result<Self> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidSampleTime { h });
        }
        check_order(order)?;
        let nyquist = 0.5 / h;
        if !(cutoff.is_finite() && cutoff > 0.0 && cutoff < nyquist) {
            return Err(Error::InvalidOption {
                option: "cutoff".into(),
                reason: format!(
                    "cutoff must lie in (0, {nyquist:.1} Hz) (the Nyquist frequency for h = {h:.6e} s), got {cutoff} Hz"
                ),
            });
        }
        // Pre-warped cutoff times h/2: the bilinear map is z = (1 + s h/2)/(1 − s h/2).
        let k = (PI * cutoff * h).tan();
        let n = order as f64;
        let mut sections: Vec<Biquad> = (1..=order / 2)
            .map(|m| {
                let angle = 0.5 * PI + (2.0 * m as f64 - 1.0) * PI / (2.0 * n);
                let s = Complex::from_polar(k, angle);
                let one = Complex::new(1.0, 0.0);
                let z = (one + s) / (one - s);
                let (a1, a2) = (-2.0 * z.re, z.norm_sqr());
                let g = 0.25 * (1.0 + a1 + a2);
                Biquad { b: [g, 2.0 * g, g], a: [1.0, a1, a2] }
            })
            .collect();
        sections.sort_by(|x, y| x.a[2].total_cmp(&y.a[2]));
        Ok(Self { order, cutoff, h, sections })
    }

    /// Filter order n.
    pub fn order(&self) -> usize {
        self.order
    }
    /// Cutoff frequency f_c \[Hz\] (−3 dB per pass).
    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }
    /// Sample time h \[s\].
    pub fn h(&self) -> f64 {
        self.h
    }
    /// The second-order sections, n/2 of them, by increasing pole radius; each has unit DC
    /// gain (scipy puts the whole gain into the first section instead: the product of the
    /// `b0` is the same).
    pub fn sections(&self) -> &[Biquad] {
        &self.sections
    }

    /// Frequency response `H(e^{j 2π f h})` of one (causal) pass at frequency `f` \[Hz\].
    ///
    /// The forward-backward filter's response is `|H|²`, real and non-negative.
    pub fn frequency_response(&self, f: f64) -> Complex<f64> {
        let w = Complex::from_polar(1.0, -2.0 * PI * f * self.h);
        self.sections.iter().map(|s| s.response(w)).product()
    }

    /// Time constant of the slowest pole, `−1/ln|z|_max` \[samples\].
    pub fn time_constant(&self) -> f64 {
        let r2 = self.sections.iter().map(|s| s.a[2]).fold(0.0, f64::max);
        -2.0 / r2.ln()
    }

    /// Samples of odd reflection added at each end by [`Butterworth::filtfilt`] for a
    /// record of `n` samples: `max(3 (2 n_s + 1), ⌈PAD_TIME_CONSTANTS · τ⌉)` with n_s the
    /// number of sections and τ [`Butterworth::time_constant`], at most `n − 1`.
    ///
    /// The first term is scipy's default `padlen` for `sosfiltfilt`; the second lets the
    /// transient of a non-constant edge decay by `e^{−10}` before the record starts.
    pub fn pad_len(&self, n: usize) -> usize {
        let scipy = 3 * (2 * self.sections.len() + 1);
        let tau = (PAD_TIME_CONSTANTS * self.time_constant()).ceil();
        let by_tau = if tau.is_finite() { tau as usize } else { usize::MAX };
        scipy.max(by_tau).min(n.saturating_sub(1))
    }

    /// Causal filtering from rest (zero initial state), length of `x` (`scipy.signal.sosfilt`).
    pub fn filter(&self, x: &[f64]) -> Vec<f64> {
        let mut z = vec![[0.0; 2]; self.sections.len()];
        x.iter().map(|&v| self.step(&mut z, v)).collect()
    }

    /// Zero-phase forward-backward filtering of `x` (same length), odd reflection padding
    /// of [`Butterworth::pad_len`] samples and steady-state initial conditions per section
    /// (`scipy.signal.sosfiltfilt(sos, x, padtype='odd', padlen=pad_len(x.len()))`).
    ///
    /// A constant record passes unchanged; the response is `|H(f)|²` with zero phase.
    /// Non-finite input gives non-finite output.
    pub fn filtfilt(&self, x: &[f64]) -> Vec<f64> {
        let n = x.len();
        if n == 0 {
            return Vec::new();
        }
        let p = self.pad_len(n);
        let mut ext = Vec::with_capacity(n + 2 * p);
        ext.extend((0..p).map(|i| 2.0 * x[0] - x[p - i]));
        ext.extend_from_slice(x);
        ext.extend((0..p).map(|j| 2.0 * x[n - 1] - x[n - 2 - j]));
        let zi: Vec<[f64; 2]> = self.steady_states();
        let mut z: Vec<[f64; 2]> = zi.iter().map(|s| [s[0] * ext[0], s[1] * ext[0]]).collect();
        for v in ext.iter_mut() {
            *v = self.step(&mut z, *v);
        }
        let last = ext[ext.len() - 1];
        let mut z: Vec<[f64; 2]> = zi.iter().map(|s| [s[0] * last, s[1] * last]).collect();
        for v in ext.iter_mut().rev() {
            *v = self.step(&mut z, *v);
        }
        ext[p..p + n].to_vec()
    }

    /// The experiment with every channel filtered by [`Butterworth::filtfilt`] except
    /// those named in `keep` (e.g. a wrapped angle), which pass through unchanged.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `sample time`) when the filter was designed for a
    /// sample time other than the experiment's (relative difference above 10⁻⁹).
    pub fn filtfilt_experiment(&self, e: &Experiment, keep: &[&str]) -> Result<Experiment> {
        if (e.h() - self.h).abs() > 1e-9 * self.h {
            return Err(Error::InvalidOption {
                option: "sample time".into(),
                reason: format!(
                    "filter designed for h = {:e} s, experiment `{}` has h = {:e} s",
                    self.h,
                    e.name(),
                    e.h()
                ),
            });
        }
        let channels = e
            .channels()
            .iter()
            .map(|c| {
                let values = if keep.contains(&c.name.as_str()) {
                    c.values.clone()
                } else {
                    self.filtfilt(&c.values).into()
                };
                Channel { name: c.name.clone(), unit: c.unit.clone(), values }
            })
            .collect();
        Ok(Experiment::try_new(e.name(), e.h(), channels)?.with_t0(e.t0()))
    }

    /// Initial states per section for a constant input 1 through the whole cascade
    /// (`scipy.signal.sosfilt_zi`).
    fn steady_states(&self) -> Vec<[f64; 2]> {
        let mut scale = 1.0;
        self.sections
            .iter()
            .map(|s| {
                let [z1, z2] = s.steady_state();
                let out = [scale * z1, scale * z2];
                scale *= s.dc_gain();
                out
            })
            .collect()
    }

    /// One sample through the causal cascade (transposed direct form II); `z` holds the
    /// state of every section (length [`sections`](Self::sections)`.len()`, zeros = at rest).
    /// This is the streaming form of [`filter`](Self::filter), used for the residual
    /// prefilter L(q) of the prediction-error fit.
    #[inline]
    pub fn step(&self, z: &mut [[f64; 2]], x: f64) -> f64 {
        let mut v = x;
        for (s, zs) in self.sections.iter().zip(z.iter_mut()) {
            let y = s.b[0] * v + zs[0];
            zs[0] = s.b[1] * v - s.a[1] * y + zs[1];
            zs[1] = s.b[2] * v - s.a[2] * y;
            v = y;
        }
        v
    }
}
