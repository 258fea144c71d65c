//! Parameter scaling: the map between a physical parameter θ and the scaled variable p
//! the optimiser moves.
//!
//! Parameters of a motor differ by orders of magnitude (`L_s ≈ 10⁻³ H`, `R_s ≈ 1 Ω`);
//! optimising in scaled variables of order one makes the damping, the tolerances and the
//! finite-difference steps (`∛ε` in p, i.e. relative to the scale) meaningful for every
//! parameter at once. Source: Dennis & Schnabel, *Numerical Methods for Unconstrained
//! Optimization and Nonlinear Equations* (1983), section 7.1; Moré (1978), "The
//! Levenberg-Marquardt algorithm: implementation and theory" (column-norm scaling).

use crate::error::{Error, Result};
use crate::model::Parameter;
use serde::{Deserialize, Serialize};

/// The transform of one parameter, `θ = T(p)`; monotone increasing.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Transform {
    /// `θ = scale · p` (scale > 0).
    Linear {
        /// θ per unit p, in θ's unit.
        scale: f64,
    },
    /// `θ = reference · e^p` (reference > 0): keeps θ positive.
    Log {
        /// θ at p = 0, in θ's unit.
        reference: f64,
    },
}

impl Transform {
    /// θ from p.
    #[inline]
    pub fn to_theta(&self, p: f64) -> f64 {
        match *self {
            Self::Linear { scale } => scale * p,
            Self::Log { reference } => reference * p.exp(),
        }
    }
    /// p from θ (θ > 0 for [`Transform::Log`], else −∞ or NaN).
    #[inline]
    pub fn to_scaled(&self, theta: f64) -> f64 {
        match *self {
            Self::Linear { scale } => theta / scale,
            Self::Log { reference } => {
                if theta > 0.0 {
                    (theta / reference).ln()
                } else {
                    f64::NEG_INFINITY
                }
            }
        }
    }
    /// Derivative `dθ/dp` at p.
    #[inline]
    pub fn dtheta_dp(&self, p: f64) -> f64 {
        match *self {
            Self::Linear { scale } => scale,
            Self::Log { reference } => reference * p.exp(),
        }
    }
}

/// A rule that chooses the [`Transform`] of each free parameter at the start of a fit.
///
/// `start` is the parameter's start value, `column_norm` the Euclidean norm of the
/// output-sensitivity column `‖∂ŷ/∂θ‖` at the start (computed only when
/// [`needs_column_norms`](Self::needs_column_norms) is true).
pub trait ParameterScaling: Send + Sync + std::fmt::Debug {
    /// Short name for reports, e.g. `nominal`.
    fn name(&self) -> &str;
    /// Whether [`transform`](Self::transform) uses the Jacobian column norm.
    fn needs_column_norms(&self) -> bool {
        false
    }
    /// The transform for parameter `param` starting at `start`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] when the rule cannot apply (e.g. log scaling of a
    /// parameter whose start is not positive).
    fn transform(&self, param: &Parameter, start: f64, column_norm: Option<f64>) -> Result<Transform>;
}

/// `p = θ/θ_nominal`, with θ_nominal the parameter's `nominal` or, when unset, `|start|`
/// (1 if the start is 0). The default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NominalScaling;

impl ParameterScaling for NominalScaling {
    fn name(&self) -> &str {
        "nominal"
    }
    fn transform(&self, param: &Parameter, start: f64, _: Option<f64>) -> Result<Transform> {
        let scale = param.nominal.map(f64::abs).filter(|s| *s > 0.0 && s.is_finite()).unwrap_or(start.abs());
        Ok(Transform::Linear { scale: if scale > 0.0 && scale.is_finite() { scale } else { 1.0 } })
    }
}

/// `p = ln(θ/|start|)`: θ stays positive whatever step the optimiser takes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LogScaling;

impl ParameterScaling for LogScaling {
    fn name(&self) -> &str {
        "log"
    }
    fn transform(&self, param: &Parameter, start: f64, _: Option<f64>) -> Result<Transform> {
        if !(start > 0.0 && start.is_finite()) {
            return Err(Error::InvalidParameter {
                name: param.name.clone(),
                value: start,
                reason: "logarithmic scaling needs a positive start value".into(),
            });
        }
        Ok(Transform::Log { reference: start })
    }
}

/// `p = θ ‖∂ŷ/∂θ‖`: every column of the scaled Jacobian has unit norm at the start (Moré 1978).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ColumnNormScaling;

impl ParameterScaling for ColumnNormScaling {
    fn name(&self) -> &str {
        "column_norm"
    }
    fn needs_column_norms(&self) -> bool {
        true
    }
    fn transform(&self, param: &Parameter, start: f64, column_norm: Option<f64>) -> Result<Transform> {
        match column_norm {
            Some(n) if n > 0.0 && n.is_finite() => Ok(Transform::Linear { scale: 1.0 / n }),
            // A parameter the outputs do not see keeps nominal scaling; diagnostics report it.
            _ => NominalScaling.transform(param, start, None),
        }
    }
}

/// `p = θ`: no scaling.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct IdentityScaling;

impl ParameterScaling for IdentityScaling {
    fn name(&self) -> &str {
        "identity"
    }
    fn transform(&self, _: &Parameter, _: f64, _: Option<f64>) -> Result<Transform> {
        Ok(Transform::Linear { scale: 1.0 })
    }
}

/// The built-in scalings by name, for configuration files and the command line.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScalingKind {
    /// [`NominalScaling`].
    #[default]
    Nominal,
    /// [`LogScaling`].
    Log,
    /// [`ColumnNormScaling`].
    ColumnNorm,
    /// [`IdentityScaling`].
    Identity,
}

impl ScalingKind {
    /// The scaling rule.
    pub fn rule(self) -> Box<dyn ParameterScaling> {
        match self {
            Self::Nominal => Box::new(NominalScaling),
            Self::Log => Box::new(LogScaling),
            Self::ColumnNorm => Box::new(ColumnNormScaling),
            Self::Identity => Box::new(IdentityScaling),
        }
    }
}
