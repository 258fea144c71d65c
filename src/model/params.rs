//! Parameter metadata.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Metadata of one model parameter: name, unit, nominal value, bounds and fixed flag.
///
/// `nominal` sets the parameter's scale (the default scaling divides by it); `None` means
/// "use the magnitude of the start value". Bounds are inclusive, `lower < upper`, and may be
/// infinite.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Parameter {
    /// Symbol in snake case, e.g. `r_s`.
    pub name: String,
    /// SI unit, e.g. `ohm`, `H`, `V s/rad`.
    pub unit: String,
    /// Typical magnitude used for scaling and finite-difference steps; `None` = |start|.
    pub nominal: Option<f64>,
    /// Lower bound (inclusive).
    pub lower: f64,
    /// Upper bound (inclusive).
    pub upper: f64,
    /// Held at its start value during estimation.
    pub fixed: bool,
    /// A nuisance parameter: needed to explain the data (an inverter's voltage error, a
    /// delay) but not a property of the system the model describes; reports flag it.
    #[serde(default)]
    pub nuisance: bool,
}

impl Parameter {
    /// A free parameter bounded to `(0, ∞)`: the lower bound is `1e-9 × nominal`.
    pub fn positive(name: &str, unit: &str, nominal: f64) -> Self {
        Self {
            name: name.into(),
            unit: unit.into(),
            nominal: Some(nominal),
            lower: 1e-9 * nominal.abs(),
            upper: f64::INFINITY,
            fixed: false,
            nuisance: false,
        }
    }

    /// A free parameter with no bounds.
    pub fn free(name: &str, unit: &str, nominal: f64) -> Self {
        Self {
            name: name.into(),
            unit: unit.into(),
            nominal: Some(nominal),
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            fixed: false,
            nuisance: false,
        }
    }

    /// Checks that the bounds are a non-empty interval without NaN.
    ///
    /// # Errors
    /// [`Error::InvalidBounds`] naming the parameter.
    pub fn check_bounds(&self) -> Result<()> {
        let bad = |reason: &str| Error::InvalidBounds {
            name: self.name.clone(),
            lower: self.lower,
            upper: self.upper,
            reason: reason.into(),
        };
        if self.lower.is_nan() || self.upper.is_nan() {
            return Err(bad("a bound is NaN"));
        }
        if self.lower >= self.upper {
            return Err(bad("lower bound must be below upper bound"));
        }
        if self.lower == f64::INFINITY || self.upper == f64::NEG_INFINITY {
            return Err(bad("empty interval"));
        }
        Ok(())
    }

    /// Checks that `value` is finite and within the bounds.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a non-finite value, [`Error::StartOutsideBounds`]
    /// when outside `[lower, upper]`.
    pub fn check_start(&self, value: f64) -> Result<()> {
        if !value.is_finite() {
            return Err(Error::InvalidParameter {
                name: self.name.clone(),
                value,
                reason: "start value is not finite".into(),
            });
        }
        if value < self.lower || value > self.upper {
            return Err(Error::StartOutsideBounds {
                name: self.name.clone(),
                value,
                lower: self.lower,
                upper: self.upper,
            });
        }
        Ok(())
    }
}

/// A quantity derived from the estimates (e.g. a torque constant), with propagated
/// uncertainty. Built with [`new`](Self::new) outside the crate (fields may be added, as
/// `ci95` was).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct DerivedEstimate {
    /// Symbol, e.g. `k_t`.
    pub name: String,
    /// Unit, e.g. `N m/A`.
    pub unit: String,
    /// Value \[unit\].
    pub value: f64,
    /// Standard error \[unit\].
    pub std_error: f64,
    /// The 95 % interval `[low, high]` \[unit\], set by the fit that reports the quantity:
    /// a quantity that is a monotone function of one parameter takes that parameter's
    /// interval through the function (so `k_t` keeps the asymmetry of a restricted `k_e`
    /// interval, `estimate::restricted`), any other `value ± t·std_error` with the fit's
    /// quantile t. `None` from a model's [`derived`](crate::model::GreyBoxModel::derived),
    /// which does not know the fit's quantile, and in reports written before the field
    /// existed; [`interval`](Self::interval) then gives `± t·std_error`.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub ci95: Option<[f64; 2]>,
    /// Experiment, for quantities derived from per-experiment parameters.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub experiment: Option<String>,
}

impl DerivedEstimate {
    /// The quantity `name` \[`unit`\] with its value and standard error \[unit\] (the delta
    /// method, e.g. `|∂g/∂θ| se(θ)`), no interval (the fit sets it:
    /// [`with_interval`](Self::with_interval)) and no experiment. No errors.
    pub fn new(name: impl Into<String>, unit: impl Into<String>, value: f64, std_error: f64) -> Self {
        Self { name: name.into(), unit: unit.into(), value, std_error, ci95: None, experiment: None }
    }

    /// The 95 % interval \[unit\]: [`ci95`](Self::ci95), else `value ± t·std_error` with
    /// `t` the fit's 0.975 quantile (Student's t at its degrees of freedom).
    pub fn interval(&self, t: f64) -> [f64; 2] {
        self.ci95.unwrap_or([self.value - t * self.std_error, self.value + t * self.std_error])
    }

    /// `self` with its interval set: kept where it is set, else `value ± t·std_error`
    /// ([`interval`](Self::interval)); for the fits that build a report.
    pub fn with_interval(self, t: f64) -> Self {
        Self { ci95: Some(self.interval(t)), ..self }
    }
}
