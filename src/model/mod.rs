//! Grey-box models: the [`GreyBoxModel`] trait and the PMSM models.
//!
//! A model is a discrete-time state-space system over one sample period,
//! `x[k+1] = f(x[k], inputs[k], θ)`, `ŷ[k] = g(x[k], inputs[k], θ)`, whose parameters θ
//! carry physical meaning. The estimator drives [`GreyBoxModel::step`] sample by sample;
//! nothing else (simulation, estimation, reports) depends on the model type.
//!
//! Two kinds of per-sample work are kept apart so that the inner loop stays short:
//! quantities that depend on the data only (interval-mean speed, the rotation
//! `e^{−jω_e h}`, the held voltage) are computed once per experiment by
//! [`GreyBoxModel::prepare`]; quantities that depend on θ only (`e^{−R_s h/L_s}`, `1/L_s`)
//! once per parameter vector by [`GreyBoxModel::coefficients`].

pub mod ipm;
pub mod params;
pub mod spm;

pub use ipm::PmsmIpm;
pub use params::Parameter;
pub use spm::PmsmSpm;

use crate::data::Experiment;
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// How the voltage is held between samples (MODEL.md §4).
///
/// An inverter holds its output constant in the **stator** frame over a period, so in dq
/// it rotates backwards by `φ = ω_e h`; some simulators hold the **dq** voltage constant.
/// Each is exact for its source and wrong at second order in φ for the other.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum VoltageHold {
    /// `u_dq` constant over `[t_k, t_k + h)`.
    Dq,
    /// `u_αβ` constant over the period; `u[k]` is the period mean of the rotating dq voltage.
    #[default]
    Stator,
}

impl std::fmt::Display for VoltageHold {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Dq => "dq",
            Self::Stator => "stator",
        })
    }
}

/// The data a model needs from one experiment, prepared once before fitting.
///
/// `y` holds the measured outputs row-major, `y[k n_y + i]` = output i at sample k,
/// length `N n_y`; `x0` the initial state taken from the measurement at k = 0 (length n_x).
#[derive(Clone, Debug)]
pub struct Prepared<I> {
    /// Experiment name (for error messages and reports).
    pub name: String,
    /// Number of samples N.
    pub n: usize,
    /// Measured outputs, row-major `N × n_y`.
    pub y: Vec<f64>,
    /// Initial state from the measurement at k = 0, length n_x.
    pub x0: Vec<f64>,
    /// Model-specific, θ-independent per-sample data (inputs, rotations, speeds).
    pub inputs: I,
}

impl<I> Prepared<I> {
    /// Measured output vector at sample k, length n_y.
    ///
    /// # Panics
    /// If `(k + 1) n_y` exceeds `y.len()` (k ≥ N for consistent data).
    pub fn y_at(&self, k: usize, n_y: usize) -> &[f64] {
        &self.y[k * n_y..(k + 1) * n_y]
    }
}

/// A discrete-time grey-box model with physical parameters.
///
/// Shapes: state `x` has length [`n_states`](Self::n_states) = n_x, output `y` length
/// [`n_outputs`](Self::n_outputs) = n_y, parameters θ length `parameters().len()` = n_θ.
/// Sensitivities `s = ∂x/∂θ` are row-major `n_x × n_θ` (`s[i n_θ + j] = ∂x_i/∂θ_j`).
///
/// Implementors must not panic on any θ within the parameters' bounds; invalid θ is
/// reported by [`coefficients`](Self::coefficients). A model without analytic
/// sensitivities returns `false` from [`has_sensitivities`](Self::has_sensitivities) and
/// the estimator falls back to central finite differences of [`step`](Self::step)
/// (through `finitediff`, steps relative to the scaled parameter).
///
/// # Example: a first-order RL circuit (dq hold, speed ignored)
/// ```
/// use greybox::model::{GreyBoxModel, Parameter, Prepared};
/// use greybox::{Experiment, Result};
///
/// struct Rl { p: Vec<Parameter> }
/// impl GreyBoxModel for Rl {
///     type Inputs = (f64, Vec<f64>);       // (h, u_d)
///     type Coefficients = (f64, f64);      // (a, b)
///     fn name(&self) -> &str { "rl" }
///     fn n_states(&self) -> usize { 1 }
///     fn n_outputs(&self) -> usize { 1 }
///     fn output_names(&self) -> Vec<String> { vec!["i_d".into()] }
///     fn parameters(&self) -> &[Parameter] { &self.p }
///     fn prepare(&self, e: &Experiment) -> Result<Prepared<Self::Inputs>> {
///         Ok(Prepared { name: e.name().into(), n: e.len(), y: e.i_d().to_vec(),
///                       x0: vec![e.i_d()[0]], inputs: (e.h(), e.u_d().to_vec()) })
///     }
///     fn coefficients(&self, th: &[f64], inp: &Self::Inputs) -> Result<Self::Coefficients> {
///         let a = (-th[0] * inp.0 / th[1]).exp();
///         Ok((a, (1.0 - a) / th[0]))
///     }
///     fn step(&self, c: &Self::Coefficients, inp: &Self::Inputs, k: usize, x: &[f64], xn: &mut [f64]) {
///         xn[0] = c.0 * x[0] + c.1 * inp.1[k];
///     }
/// }
/// let m = Rl { p: vec![Parameter::positive("r", "ohm", 1.0), Parameter::positive("l", "H", 1e-3)] };
/// assert_eq!(m.parameters().len(), 2);
/// ```
pub trait GreyBoxModel: Sync {
    /// θ-independent per-sample data derived from an experiment.
    type Inputs: Send + Sync;
    /// θ-dependent, sample-independent coefficients (computed once per θ).
    type Coefficients: Send + Sync;

    /// Short identifier used in reports, e.g. `pmsm_spm`.
    fn name(&self) -> &str;
    /// State dimension n_x.
    fn n_states(&self) -> usize;
    /// Output dimension n_y.
    fn n_outputs(&self) -> usize;
    /// Output names, length n_y, e.g. `["i_d", "i_q"]`.
    fn output_names(&self) -> Vec<String>;
    /// Parameter metadata (name, unit, nominal value, bounds, fixed flag), length n_θ.
    fn parameters(&self) -> &[Parameter];
    /// Unit of state i, for reports (default: empty).
    fn state_unit(&self, _i: usize) -> String {
        String::new()
    }

    /// Extracts inputs, measured outputs and the initial state from an experiment.
    ///
    /// # Errors
    /// Model-specific: e.g. a missing optional signal the model needs.
    fn prepare(&self, experiment: &Experiment) -> Result<Prepared<Self::Inputs>>;

    /// Computes the θ-dependent coefficients, validating θ (length n_θ, model order, SI units).
    ///
    /// # Errors
    /// [`crate::Error::InvalidParameter`] for a θ the model cannot simulate (e.g. `L ≤ 0`);
    /// [`crate::Error::InvalidOption`] for θ of the wrong length (built-in models).
    fn coefficients(&self, theta: &[f64], inputs: &Self::Inputs) -> Result<Self::Coefficients>;

    /// One sample period: `x_next = f(x, inputs[k], θ)` for `k < N − 1`.
    fn step(&self, c: &Self::Coefficients, inputs: &Self::Inputs, k: usize, x: &[f64], x_next: &mut [f64]);

    /// Output map `y = g(x)`; the default takes the first n_y states.
    fn output(&self, _c: &Self::Coefficients, _inputs: &Self::Inputs, _k: usize, x: &[f64], y: &mut [f64]) {
        let n = y.len();
        y.copy_from_slice(&x[..n]);
    }

    /// Whether [`step_sensitivity`](Self::step_sensitivity) and
    /// [`output_sensitivity`](Self::output_sensitivity) are implemented analytically.
    fn has_sensitivities(&self) -> bool {
        false
    }

    /// One period with forward sensitivities: `x_next` as [`step`](Self::step) and
    /// `s_next = ∂x_next/∂x · s + ∂x_next/∂θ` (row-major `n_x × n_θ`).
    ///
    /// Only called when [`has_sensitivities`](Self::has_sensitivities) is true; the
    /// default falls back to [`step`](Self::step) with `s_next = 0`, which the estimator
    /// never relies on.
    #[allow(clippy::too_many_arguments)]
    fn step_sensitivity(
        &self,
        c: &Self::Coefficients,
        inputs: &Self::Inputs,
        k: usize,
        x: &[f64],
        _s: &[f64],
        x_next: &mut [f64],
        s_next: &mut [f64],
    ) {
        self.step(c, inputs, k, x, x_next);
        s_next.fill(0.0);
    }

    /// Output sensitivity `∂y/∂θ = ∂g/∂x · s + ∂g/∂θ` (row-major `n_y × n_θ`); the default
    /// (for `y` = first n_y states) copies the first n_y rows of `s`.
    fn output_sensitivity(
        &self,
        _c: &Self::Coefficients,
        _inputs: &Self::Inputs,
        _k: usize,
        _x: &[f64],
        s: &[f64],
        dy: &mut [f64],
    ) {
        let n = dy.len();
        dy.copy_from_slice(&s[..n]);
    }

    /// Directional derivative of the step with respect to the state,
    /// `out = ∂x_next/∂x · v` (lengths n_x); propagates the sensitivity to an estimated
    /// initial state. The default is a central difference with step
    /// `1e-4 (1 + |x|)/|v|`, exact to rounding for models affine in the state (as the PMSM).
    #[allow(clippy::too_many_arguments)]
    fn step_state_derivative(
        &self,
        c: &Self::Coefficients,
        inputs: &Self::Inputs,
        k: usize,
        x: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        directional_difference(x, v, out, |xs, o| self.step(c, inputs, k, xs, o));
    }

    /// Directional derivative of the output map, `out = ∂y/∂x · v` (v length n_x, out
    /// length n_y); the default is a central difference of [`output`](Self::output).
    fn output_state_derivative(
        &self,
        c: &Self::Coefficients,
        inputs: &Self::Inputs,
        k: usize,
        x: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        directional_difference(x, v, out, |xs, o| self.output(c, inputs, k, xs, o));
    }
}

/// Central difference of `f` at x along direction v, step `1e-4 (1 + ‖x‖)/‖v‖`:
/// `out = (f(x + d v) − f(x − d v))/(2d)`.
fn directional_difference(x: &[f64], v: &[f64], out: &mut [f64], mut f: impl FnMut(&[f64], &mut [f64])) {
    let norm = |u: &[f64]| u.iter().map(|a| a * a).sum::<f64>().sqrt();
    let nv = norm(v);
    let d = if nv > 0.0 { 1e-4 * (1.0 + norm(x)) / nv } else { 1.0 };
    let shifted = |sign: f64| x.iter().zip(v).map(|(a, b)| a + sign * d * b).collect::<Vec<f64>>();
    let mut minus = vec![0.0; out.len()];
    f(&shifted(1.0), out);
    f(&shifted(-1.0), &mut minus);
    for (o, m) in out.iter_mut().zip(&minus) {
        *o = (*o - m) / (2.0 * d);
    }
}

/// Parameter values as `name = value` pairs, comma separated (for messages).
pub(crate) fn describe(params: &[Parameter], theta: &[f64]) -> String {
    params
        .iter()
        .zip(theta)
        .map(|(p, v)| format!("{} = {v:e} {}", p.name, p.unit))
        .collect::<Vec<_>>()
        .join(", ")
}
