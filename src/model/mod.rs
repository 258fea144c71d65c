//! Grey-box models: the [`GreyBoxModel`] trait, parameter metadata and the data a model
//! is fitted on ([`Prepared`]).
//!
//! A model is a discrete-time state-space system over one sample period,
//! `x[k+1] = f(x[k], inputs[k], θ)`, `ŷ[k] = g(x[k], inputs[k], θ)`, whose parameters θ
//! carry physical meaning. A model declares the channels it predicts
//! ([`GreyBoxModel::outputs`]); the framework reads them from an
//! [`Experiment`] into the measured `y` and, for a dynamic model,
//! the initial state. A static model (`n_x = 0`, e.g. a regression `y = f(x, θ)`) has no
//! state: every sample counts and nothing is padded. The estimator drives
//! [`GreyBoxModel::step`] sample by sample; nothing else (simulation, estimation, reports)
//! depends on the model type.
//!
//! Two kinds of per-sample work are kept apart so that the inner loop stays short:
//! quantities that depend on the data only are prepared once per experiment by
//! [`GreyBoxModel::prepare`]; quantities that depend on θ only once per parameter vector by
//! [`GreyBoxModel::coefficients`]. An experiment's channels are shared
//! ([`crate::data::Values`]): [`Prepared`] takes the measured outputs without copying them,
//! and a model whose data-only terms are cheap may keep the channels it reads and form
//! those terms block by block (the PMSM models do), so that a fit's memory beyond its data
//! does not grow with the record. Analytic forward sensitivities are a separate trait,
//! [`Sensitivities`], offered through [`GreyBoxModel::sensitivities`]: a model either
//! implements them or gets finite differences, never a silent zero Jacobian.

pub(crate) mod block;
pub(crate) mod params;

pub use block::{BLOCK_LEN, Block, BlockContext, BlockKernel, SimState};
pub use params::{DerivedEstimate, Parameter};

use crate::data::{Experiment, Values};
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// A signal a model predicts (or a state it carries): channel name and SI unit.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Signal {
    /// Channel name in the experiment, e.g. `id`, `T_w`.
    pub name: String,
    /// SI unit, e.g. `A`, `K`.
    pub unit: String,
}

impl Signal {
    /// The signal `name` in `unit`.
    pub fn new(name: &str, unit: &str) -> Self {
        Self { name: name.into(), unit: unit.into() }
    }
}

/// The data a model is fitted on, prepared once per experiment by [`Prepared::new`].
///
/// `y` holds the measured outputs, one column per output (`y[i][k]` = output i at sample
/// k, each of length N), shared with the experiment rather than copied; `x0` the initial
/// state from the measurement at k = 0 (length n_x, empty for a static model).
#[derive(Clone, Debug)]
pub struct Prepared<I> {
    /// Experiment name (for error messages and reports).
    pub name: String,
    /// Number of samples N.
    pub n: usize,
    /// Measured outputs, n_y columns of length N (the experiment's channels, shared).
    pub y: Vec<Values>,
    /// Initial state from the measurement at k = 0, length n_x.
    pub x0: Vec<f64>,
    /// Model-specific, θ-independent data (inputs, rotations, speeds, or the shared channels
    /// they are formed from).
    pub inputs: I,
}

impl<I> Prepared<I> {
    /// Takes the model's declared output channels of `e` as `y` (shared, not copied), the
    /// initial state from the first sample ([`GreyBoxModel::initial_state`]) and the
    /// model's inputs ([`GreyBoxModel::prepare`]).
    ///
    /// # Errors
    /// [`crate::Error::MissingChannel`] naming an output channel `e` lacks; those of
    /// [`GreyBoxModel::prepare`].
    pub fn new<M: GreyBoxModel<Inputs = I> + ?Sized>(model: &M, e: &Experiment) -> Result<Self> {
        let y = model.outputs().iter().map(|o| e.values(&o.name).cloned()).collect::<Result<Vec<_>>>()?;
        let n = e.len();
        let mut x0 = vec![0.0; model.n_states()];
        let y0: Vec<f64> = y.iter().map(|c| c.first().copied().unwrap_or(0.0)).collect();
        model.initial_state(&y0, &mut x0);
        Ok(Self { name: e.name().into(), n, y, x0, inputs: model.prepare(e)? })
    }

    /// The measured output vector at sample k into `out` (length n_y; a shorter `out` gets
    /// the first outputs).
    ///
    /// # Panics
    /// If k ≥ N.
    pub fn y_at(&self, k: usize, out: &mut [f64]) {
        for (o, c) in out.iter_mut().zip(&self.y) {
            *o = c[k];
        }
    }

    /// The measured outputs row-major, `N × n_y` (`[k n_y + i]` = output i at sample k): a
    /// copy, for reports.
    pub fn y_rows(&self) -> Vec<f64> {
        (0..self.n).flat_map(|k| self.y.iter().map(move |c| c[k])).collect()
    }
}

/// A discrete-time grey-box model with physical parameters.
///
/// Shapes: state `x` has length [`n_states`](Self::n_states) = n_x (0 for a static model),
/// output `y` length n_y = `outputs().len()`, parameters θ length `parameters().len()` =
/// n_θ. Sensitivities `s = ∂x/∂θ` are row-major `n_x × n_θ` (`s[i n_θ + j] = ∂x_i/∂θ_j`).
///
/// Implementors must not panic on any θ within the parameters' bounds; invalid θ is
/// reported by [`coefficients`](Self::coefficients). A model without analytic
/// sensitivities returns `None` from [`sensitivities`](Self::sensitivities) (the default)
/// and the estimator uses central finite differences of [`step`](Self::step) and
/// [`output`](Self::output) (through `finitediff`, steps relative to the scaled parameter).
///
/// # Example: a first-order RL circuit
/// ```
/// use greybox::model::{GreyBoxModel, Parameter, Signal};
/// use greybox::{Experiment, Result};
///
/// struct Rl { p: Vec<Parameter> }
/// impl GreyBoxModel for Rl {
///     type Inputs = (f64, Vec<f64>);       // (h, u)
///     type Coefficients = (f64, f64);      // (a, b)
///     fn name(&self) -> &str { "rl" }
///     fn n_states(&self) -> usize { 1 }
///     fn outputs(&self) -> Vec<Signal> { vec![Signal::new("i", "A")] }
///     fn input_channels(&self) -> Vec<String> { vec!["u".into()] }
///     fn parameters(&self) -> &[Parameter] { &self.p }
///     fn prepare(&self, e: &Experiment) -> Result<Self::Inputs> {
///         Ok((e.h(), e.channel("u")?.to_vec()))
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
    /// θ-independent data derived from an experiment (per-sample arrays, or the shared
    /// channels a model forms its per-sample terms from).
    type Inputs: Send + Sync;
    /// θ-dependent, sample-independent coefficients (computed once per θ).
    type Coefficients: Send + Sync;

    /// Short identifier used in reports, e.g. `pmsm_spm`; the default is the type's name
    /// without its module path.
    fn name(&self) -> &str {
        let full = std::any::type_name::<Self>();
        let base = full.split('<').next().unwrap_or(full);
        base.rsplit("::").next().unwrap_or(base)
    }
    /// State dimension n_x; 0 for a static model.
    fn n_states(&self) -> usize;
    /// The channels the model predicts, length n_y; the measured `y` is read from them.
    fn outputs(&self) -> Vec<Signal>;
    /// The channels [`prepare`](Self::prepare) reads (for documentation and reports).
    fn input_channels(&self) -> Vec<String>;
    /// Parameter metadata (name, unit, nominal value, bounds, fixed flag), length n_θ.
    fn parameters(&self) -> &[Parameter];

    /// Output dimension n_y (the length of [`outputs`](Self::outputs)).
    fn n_outputs(&self) -> usize {
        self.outputs().len()
    }
    /// The states, length n_x (names of the initial states in reports); the default names
    /// state i after output i when the state is the output, `x[i]` otherwise.
    fn states(&self) -> Vec<Signal> {
        let outputs = self.outputs();
        (0..self.n_states())
            .map(|i| match outputs.get(i) {
                Some(o) if self.n_states() == outputs.len() => o.clone(),
                _ => Signal::new(&format!("x[{i}]"), ""),
            })
            .collect()
    }
    /// The initial state implied by the first measured output `y0` (length n_y) into `x0`
    /// (length n_x). The default copies the first outputs and zeroes the rest: right for a
    /// model whose state is its output.
    fn initial_state(&self, y0: &[f64], x0: &mut [f64]) {
        x0.fill(0.0);
        for (x, y) in x0.iter_mut().zip(y0) {
            *x = *y;
        }
    }

    /// Advice when parameter `name` (with `[experiment]` for a per-experiment copy) is
    /// poorly determined: what data would excite it. `None` (the default) gives a generic
    /// text.
    fn advice(&self, _name: &str) -> Option<String> {
        None
    }
    /// Advice when parameters `a` and `b` are strongly correlated; `None` (the default)
    /// gives a generic text.
    fn pair_advice(&self, _a: &str, _b: &str) -> Option<String> {
        None
    }
    /// What to check when an output fits poorly; `None` (the default) gives none.
    fn poor_fit_advice(&self) -> Option<String> {
        None
    }
    /// Physical constraints the estimate θ (length n_θ, one experiment's) violates, each a
    /// message naming the parameter, its value and the likely cause (e.g. a negative
    /// back-EMF constant: a speed column of the other sign). A violation makes the fit
    /// untrusted (warning `non_physical`). The default declares none.
    fn implausible(&self, _theta: &[f64]) -> Vec<String> {
        Vec::new()
    }
    /// Quantities derived from the parameters θ (length n_θ) with standard errors from
    /// their covariance (n_θ × n_θ rows, θ units; 0 for fixed parameters, ∞ on the diagonal
    /// of an unidentified one) by first-order propagation, `σ_f² = ∇fᵀ C ∇f` (e.g. a torque
    /// constant from a back-EMF constant, a time constant from a product). Leave
    /// [`DerivedEstimate::ci95`] `None`: the fit sets `± t·std_error` at its quantile (a set
    /// interval is kept as given). The default derives nothing.
    fn derived(&self, _theta: &[f64], _covariance: &[Vec<f64>]) -> Vec<DerivedEstimate> {
        Vec::new()
    }

    /// Extracts the θ-independent inputs from an experiment.
    ///
    /// # Errors
    /// [`crate::Error::MissingChannel`] for a channel the model reads, or model-specific.
    fn prepare(&self, experiment: &Experiment) -> Result<Self::Inputs>;

    /// Computes the θ-dependent coefficients, validating θ (length n_θ, model order, SI units).
    ///
    /// # Errors
    /// [`crate::Error::InvalidParameter`] for a θ the model cannot simulate (e.g. `L ≤ 0`);
    /// [`crate::Error::InvalidOption`] for θ of the wrong length (built-in models).
    fn coefficients(&self, theta: &[f64], inputs: &Self::Inputs) -> Result<Self::Coefficients>;

    /// One sample period: `x_next = f(x, inputs[k], θ)` for `k < N − 1` (nothing to do for
    /// a static model).
    fn step(&self, c: &Self::Coefficients, inputs: &Self::Inputs, k: usize, x: &[f64], x_next: &mut [f64]);

    /// Output map `y = g(x, inputs[k], θ)`; the default takes the first n_y states (a
    /// static model must override it).
    fn output(&self, _c: &Self::Coefficients, _inputs: &Self::Inputs, _k: usize, x: &[f64], y: &mut [f64]) {
        let n = y.len().min(x.len());
        y[..n].copy_from_slice(&x[..n]);
    }

    /// The analytic forward sensitivities, when the model has them; `None` (the default)
    /// makes the estimator use finite differences.
    fn sensitivities(&self) -> Option<&dyn Sensitivities<Self::Inputs, Self::Coefficients>> {
        None
    }

    /// The whole-block kernel, when the model has one: the same numbers as
    /// [`step`](Self::step), [`output`](Self::output) and the analytic
    /// [`sensitivities`](Self::sensitivities) a block of samples at a time. `None` (the
    /// default) runs those per sample.
    fn block_kernel(&self) -> Option<&dyn BlockKernel<Self::Inputs, Self::Coefficients>> {
        None
    }

    /// Directional derivative of the step with respect to the state,
    /// `out = ∂x_next/∂x · v` (lengths n_x); propagates the sensitivity to an estimated
    /// initial state. The default is a central difference with step
    /// `1e-4 (1 + |x|)/|v|`, exact to rounding for models affine in the state (as the PMSM).
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

/// Analytic forward sensitivities of a [`GreyBoxModel`] with inputs `I` and coefficients
/// `C` (Ljung, *System Identification*, 2nd ed., 10.3: the sensitivity recursion).
pub trait Sensitivities<I, C>: Sync {
    /// One period with forward sensitivities: `x_next` as [`GreyBoxModel::step`] and
    /// `s_next = ∂x_next/∂x · s + ∂x_next/∂θ` (row-major `n_x × n_θ`).
    #[allow(clippy::too_many_arguments)]
    fn step_sensitivity(
        &self,
        c: &C,
        inputs: &I,
        k: usize,
        x: &[f64],
        s: &[f64],
        x_next: &mut [f64],
        s_next: &mut [f64],
    );

    /// Output sensitivity `∂y/∂θ = ∂g/∂x · s + ∂g/∂θ` (row-major `n_y × n_θ`). For a
    /// model whose output is its first n_y states this copies the first n_y rows of `s`.
    fn output_sensitivity(&self, c: &C, inputs: &I, k: usize, x: &[f64], s: &[f64], dy: &mut [f64]);
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
