//! Simulation of a [`GreyBoxModel`]: single shooting from the measured (or a given) first
//! state, with forward sensitivities, streamed sample by sample; one [`SimOptions`] says
//! how.
//!
//! [`simulate`] returns the predicted outputs; [`visit_sensitivities`] calls a closure with
//! `ŷ_k`, `∂ŷ_k/∂θ` and optionally `∂ŷ_k/∂x₀` at every sample, so that an estimator can accumulate the normal
//! equations `JᵀJ`, `Jᵀε` in one pass without ever storing the `N n_y × n_θ` Jacobian.
//! Models without analytic sensitivities get them from central finite differences of
//! their step (crate `finitediff`), with steps relative to each parameter's scale.
//!
//! Source: forward sensitivity analysis of a discrete recursion, e.g. Ljung, *System
//! Identification* (2nd ed.), section 10.3; thesis section 5.3 (Tenerz 2011).

mod blocks;
mod fd;

pub use blocks::simulate_blocks;

use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Prepared, describe};

/// How a simulation runs: restarts, initial state, sensitivities. Plain data with
/// defaults (pure simulation from the measured first state).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SimOptions<'a> {
    /// Restart period in samples: `None` simulates the whole record (output error);
    /// `Some(k)` restarts the state from the measured output every k samples (k-step-ahead
    /// prediction; `k = 1` is one-step-ahead prediction, i.e. equation error). Restarting
    /// needs a model whose state is its output (`n_x = n_y`).
    pub horizon: Option<usize>,
    /// Initial state (length n_x); `None` = the measured one ([`Prepared::x0`]).
    pub x0: Option<&'a [f64]>,
    /// Also give `∂ŷ_k/∂x₀` to [`visit_sensitivities`]'s closure.
    pub x0_sensitivity: bool,
    /// Each parameter's scale (length n_θ, positive): sets the finite-difference step
    /// (`∛ε × scale`) for models without analytic sensitivities; `None` = `|θ|` (1 where θ = 0).
    pub fd_scale: Option<&'a [f64]>,
}

impl SimOptions<'_> {
    /// Whether the state is reset to the measurement after the output at sample k.
    pub(crate) fn restarts_at(&self, k: usize) -> bool {
        matches!(self.horizon, Some(h) if k.is_multiple_of(h))
    }
}

/// Simulated outputs `ŷ`, row-major `N × n_y`.
///
/// # Errors
/// Those of [`GreyBoxModel::coefficients`] for an invalid θ;
/// [`Error::SimulationDiverged`] naming the experiment, the sample and θ when the state
/// stops being finite; [`Error::InvalidOption`] for θ not of length n_θ, an `x0` not of
/// length n_x, prepared data of inconsistent shape, a zero horizon or a horizon on a
/// model whose state is not its output.
pub fn simulate<M: GreyBoxModel>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    options: &SimOptions<'_>,
) -> Result<Vec<f64>> {
    let x0 = options.x0.unwrap_or(&prep.x0);
    check_shooting(model, options.horizon)?;
    check_inputs(model, prep, theta, x0)?;
    let (nx, ny) = (model.n_states(), model.n_outputs());
    let c = model.coefficients(theta, &prep.inputs)?;
    let mut yhat = vec![0.0; prep.n * ny];
    let mut x = x0.to_vec();
    let mut xn = vec![0.0; nx];
    for k in 0..prep.n {
        model.output(&c, &prep.inputs, k, &x, &mut yhat[k * ny..(k + 1) * ny]);
        if options.restarts_at(k) {
            prep.y_at(k, &mut x);
        }
        if k + 1 < prep.n && nx > 0 {
            model.step(&c, &prep.inputs, k, &x, &mut xn);
            if !xn.iter().all(|v| v.is_finite()) {
                return Err(diverged(model, prep, theta, k + 1));
            }
            std::mem::swap(&mut x, &mut xn);
        }
    }
    if let Some(k) = yhat.iter().position(|v| !v.is_finite()) {
        return Err(diverged(model, prep, theta, k / ny.max(1)));
    }
    Ok(yhat)
}

/// Calls `visit(k, ŷ_k, ∂ŷ_k/∂θ, ∂ŷ_k/∂x₀)` for every sample `k = 0..N`, with `ŷ_k` of
/// length n_y, `∂ŷ_k/∂θ` row-major `n_y × n_θ` and `∂ŷ_k/∂x₀` row-major `n_y × n_x` when
/// `options.x0_sensitivity` (empty otherwise).
///
/// The state sensitivity starts at zero and restarts likewise every `options.horizon`
/// samples; after a restart the state no longer depends on x₀ and that sensitivity is
/// zero.
///
/// # Errors
/// As [`simulate`]; [`Error::InvalidOption`] for `fd_scale` of the wrong length.
pub fn visit_sensitivities<M, F>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    options: &SimOptions<'_>,
    mut visit: F,
) -> Result<()>
where
    M: GreyBoxModel,
    F: FnMut(usize, &[f64], &[f64], &[f64]),
{
    let (ny, nth) = (model.n_outputs(), theta.len());
    let n0 = if options.x0_sensitivity { model.n_states() } else { 0 };
    let (mut y, mut dy, mut dy0) = (vec![0.0; ny], vec![0.0; ny * nth], vec![0.0; ny * n0]);
    simulate_blocks(model, prep, theta, options, true, |b| {
        for t in 0..b.len {
            for i in 0..ny {
                y[i] = b.y(i)[t];
                for j in 0..nth {
                    dy[i * nth + j] = b.dy(i, j)[t];
                }
                for m in 0..n0 {
                    dy0[i * n0 + m] = b.dy0(i, m)[t];
                }
            }
            visit(b.k0 + t, &y, &dy, &dy0);
        }
        Ok(())
    })
}

/// Checks the shapes a model and its prepared data must agree on, so that a wrong θ or a
/// user model's inconsistent `prepare` gives an error instead of an index panic.
pub(crate) fn check_inputs<M: GreyBoxModel>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    x0: &[f64],
) -> Result<()> {
    let bad = |option: &str, reason: String| Err(Error::InvalidOption { option: option.into(), reason });
    let (nx, ny, nth) = (model.n_states(), model.n_outputs(), model.parameters().len());
    if theta.len() != nth {
        return bad(
            "theta",
            format!("{} values for model `{}` with {nth} parameters", theta.len(), model.name()),
        );
    }
    if x0.len() != nx {
        return bad("x0", format!("{} values for model `{}` with {nx} states", x0.len(), model.name()));
    }
    let min = if nx > 0 { 2 } else { 1 };
    if prep.n < min || prep.y.len() != ny || prep.y.iter().any(|c| c.len() != prep.n) {
        let lengths: Vec<usize> = prep.y.iter().map(|c| c.len()).collect();
        return bad(
            "prepared data",
            format!(
                "experiment `{}`: output columns of lengths {lengths:?} for {} samples of {ny} outputs (need N ≥ {min})",
                prep.name, prep.n
            ),
        );
    }
    if prep.x0.len() != nx {
        return bad(
            "prepared data",
            format!(
                "experiment `{}`: initial state of length {}, model has {nx} states",
                prep.name,
                prep.x0.len()
            ),
        );
    }
    Ok(())
}

pub(crate) fn check_shooting<M: GreyBoxModel>(model: &M, horizon: Option<usize>) -> Result<()> {
    match horizon {
        Some(0) => {
            Err(Error::InvalidOption { option: "horizon".into(), reason: "must be at least 1".into() })
        }
        Some(_) if model.n_states() != model.n_outputs() => Err(Error::InvalidOption {
            option: "horizon".into(),
            reason: format!(
                "model `{}` has {} states but {} outputs: restarting from measurements needs state = output",
                model.name(),
                model.n_states(),
                model.n_outputs()
            ),
        }),
        _ => Ok(()),
    }
}

pub(crate) fn diverged<M: GreyBoxModel>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    k: usize,
) -> Error {
    Error::SimulationDiverged {
        experiment: prep.name.clone(),
        sample: k,
        parameters: describe(model.parameters(), theta),
    }
}
