//! Sample and output weighting: `V(θ) = ½ Σ_k β_k ε_kᵀ Λ ε_k` (thesis eq. 5.11, MODEL.md §5).
//!
//! The per-sample weight β_k is a function of the sample, above all of a speed: in a motor
//! log some parameters are seen only at high speed, others only at low speed (thesis
//! 5.2.2, MODEL.md §6). Weighting shifts what the fit listens to; the
//! parametric error index shows the effect.

use crate::data::Experiment;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// A rule that weights samples (β_k ≥ 0) and outputs (Λ_i > 0).
pub trait Weighting: Send + Sync + std::fmt::Debug {
    /// Short description for reports, e.g. `low_speed(w0 = 50 rad/s)`.
    fn name(&self) -> String;
    /// Weight β_k ≥ 0 of sample k of experiment `e` (k = 0..N).
    fn sample_weight(&self, e: &Experiment, k: usize) -> f64;
    /// Whether every β_k is 1 (lets the estimator skip storing weights).
    fn is_uniform(&self) -> bool {
        false
    }
    /// Output weights Λ (length n_y), `None` = all 1.
    fn output_weights(&self) -> Option<Vec<f64>> {
        None
    }
    /// A term the fit subtracts from its criterion (bias-compensated least squares,
    /// [`crate::estimate::CriterionCorrection`]); `None` (the default): the plain criterion.
    fn criterion_correction(&self) -> Option<&dyn crate::estimate::CriterionCorrection> {
        None
    }
    /// Checks that `e` holds what the rule reads (called before the weights).
    ///
    /// # Errors
    /// [`Error::MissingChannel`] for a channel the rule reads.
    fn check(&self, _e: &Experiment) -> Result<()> {
        Ok(())
    }
    /// All sample weights of an experiment, length N.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] when a weight is negative or not finite, or all are zero.
    fn weights(&self, e: &Experiment) -> Result<Vec<f64>> {
        self.check(e)?;
        let w: Vec<f64> = (0..e.len()).map(|k| self.sample_weight(e, k)).collect();
        if let Some((k, v)) = w.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v >= 0.0)) {
            return Err(Error::InvalidOption {
                option: "weighting".into(),
                reason: format!(
                    "{}: weight {v} at sample {k} of `{}` is not finite and ≥ 0",
                    self.name(),
                    e.name()
                ),
            });
        }
        if w.iter().all(|v| *v == 0.0) {
            return Err(Error::InvalidOption {
                option: "weighting".into(),
                reason: format!("{}: every weight of `{}` is zero", self.name(), e.name()),
            });
        }
        Ok(w)
    }
}

/// β_k = 1 for every sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Uniform;

impl Weighting for Uniform {
    fn name(&self) -> String {
        "uniform".into()
    }
    fn is_uniform(&self) -> bool {
        true
    }
    fn sample_weight(&self, _: &Experiment, _: usize) -> f64 {
        1.0
    }
}

/// Shape of a speed-based weight β(|ω_m|), ω_m mechanical \[rad/s\].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "snake_case")]
pub enum SpeedShape {
    /// `β = 1/(1 + (|ω_m|/w0)²)`: emphasises low speed.
    LowSpeed {
        /// Corner speed \[rad/s, mechanical\], > 0.
        w0: f64,
    },
    /// `β = (|ω_m|/w0)²/(1 + (|ω_m|/w0)²)`: emphasises high speed.
    HighSpeed {
        /// Corner speed \[rad/s, mechanical\], > 0.
        w0: f64,
    },
    /// `β = 1` for `lo ≤ |ω_m| ≤ hi`, `floor` elsewhere.
    Band {
        /// Lower edge \[rad/s, mechanical\], ≥ 0.
        lo: f64,
        /// Upper edge \[rad/s, mechanical\], > lo.
        hi: f64,
        /// Weight outside the band, in \[0, 1\].
        floor: f64,
    },
}

/// Speed-based sample weighting β(ω) (thesis eq. 5.11) on the interval mean of a speed
/// channel (for a motor log, the mechanical speed).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpeedWeighting {
    channel: String,
    shape: SpeedShape,
}

impl SpeedWeighting {
    /// Weighting by the speed in `channel` \[rad/s\] with the given shape; checks the
    /// shape's parameters.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] for a non-positive or non-finite corner speed, an empty band
    /// or a floor outside \[0, 1\].
    pub fn try_new(channel: &str, shape: SpeedShape) -> Result<Self> {
        let bad = |reason: String| Err(Error::InvalidOption { option: "weighting".into(), reason });
        match shape {
            SpeedShape::LowSpeed { w0 } | SpeedShape::HighSpeed { w0 } if !(w0.is_finite() && w0 > 0.0) => {
                return bad(format!("corner speed w0 must be positive, got {w0} rad/s"));
            }
            SpeedShape::Band { lo, hi, floor }
                if !(lo >= 0.0 && hi > lo && hi.is_finite() && (0.0..=1.0).contains(&floor)) =>
            {
                return bad(format!(
                    "band needs 0 ≤ lo < hi and floor in [0, 1], got lo {lo}, hi {hi}, floor {floor}"
                ));
            }
            _ => {}
        }
        Ok(Self { channel: channel.into(), shape })
    }
    /// The shape.
    pub fn shape(&self) -> SpeedShape {
        self.shape
    }
    /// β at mechanical speed `w_m` \[rad/s\].
    pub fn beta(&self, w_m: f64) -> f64 {
        let w = w_m.abs();
        match self.shape {
            SpeedShape::LowSpeed { w0 } => 1.0 / (1.0 + (w / w0).powi(2)),
            SpeedShape::HighSpeed { w0 } => {
                let r = (w / w0).powi(2);
                r / (1.0 + r)
            }
            SpeedShape::Band { lo, hi, floor } => {
                if (lo..=hi).contains(&w) {
                    1.0
                } else {
                    floor
                }
            }
        }
    }
}

impl Weighting for SpeedWeighting {
    fn name(&self) -> String {
        match self.shape {
            SpeedShape::LowSpeed { w0 } => format!("low_speed(w0 = {w0} rad/s)"),
            SpeedShape::HighSpeed { w0 } => format!("high_speed(w0 = {w0} rad/s)"),
            SpeedShape::Band { lo, hi, floor } => format!("band({lo}..{hi} rad/s, floor {floor})"),
        }
    }
    fn sample_weight(&self, e: &Experiment, k: usize) -> f64 {
        // Sample k's residual is the end of interval k−1: weight by that interval's mean speed.
        let Ok(w) = e.channel(&self.channel) else { return f64::NAN };
        let wm = if k == 0 { w[0] } else { 0.5 * (w[k - 1] + w[k]) };
        self.beta(wm)
    }
    fn check(&self, e: &Experiment) -> Result<()> {
        e.channel(&self.channel).map(|_| ())
    }
}

/// A sample-weight closure `β(experiment, k)`.
pub type SampleWeightFn = Arc<dyn Fn(&Experiment, usize) -> f64 + Send + Sync>;

/// A user closure `β(experiment, k)` with optional output weights.
#[derive(Clone)]
pub struct CustomWeighting {
    name: String,
    f: SampleWeightFn,
    output: Option<Vec<f64>>,
}

impl CustomWeighting {
    /// Wraps `f(experiment, k) -> β_k`.
    pub fn new(
        name: impl Into<String>,
        f: impl Fn(&Experiment, usize) -> f64 + Send + Sync + 'static,
    ) -> Self {
        Self { name: name.into(), f: Arc::new(f), output: None }
    }
    /// Sets output weights Λ (checked when the fit starts).
    pub fn with_output_weights(mut self, lambda: Vec<f64>) -> Self {
        self.output = Some(lambda);
        self
    }
}

impl std::fmt::Debug for CustomWeighting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CustomWeighting").field("name", &self.name).field("output", &self.output).finish()
    }
}

impl Weighting for CustomWeighting {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn sample_weight(&self, e: &Experiment, k: usize) -> f64 {
        (self.f)(e, k)
    }
    fn output_weights(&self) -> Option<Vec<f64>> {
        self.output.clone()
    }
}

/// The built-in weightings as plain data, for options files and the command line.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum WeightingKind {
    /// [`Uniform`].
    #[default]
    Uniform,
    /// [`SpeedWeighting`] with this shape.
    Speed {
        /// The speed channel the weight reads \[rad/s\].
        channel: String,
        /// The shape β(|ω|).
        shape: SpeedShape,
    },
}

impl WeightingKind {
    /// The weighting rule.
    ///
    /// # Errors
    /// Those of [`SpeedWeighting::try_new`].
    pub fn rule(&self) -> Result<Box<dyn Weighting>> {
        Ok(match self {
            Self::Uniform => Box::new(Uniform),
            Self::Speed { channel, shape } => Box::new(SpeedWeighting::try_new(channel, *shape)?),
        })
    }
}
