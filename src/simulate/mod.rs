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
            x.copy_from_slice(prep.y_at(k, ny));
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
    let x0 = options.x0.unwrap_or(&prep.x0);
    check_shooting(model, options.horizon)?;
    check_inputs(model, prep, theta, x0)?;
    let default_scale: Vec<f64>;
    let fd_scale = match options.fd_scale {
        Some(s) => s,
        None => {
            default_scale = theta.iter().map(|t| if *t != 0.0 { t.abs() } else { 1.0 }).collect();
            &default_scale
        }
    };
    if fd_scale.len() != theta.len() {
        return Err(Error::InvalidOption {
            option: "fd_scale".into(),
            reason: format!("{} scales for {} parameters", fd_scale.len(), theta.len()),
        });
    }
    let (nx, ny, nth) = (model.n_states(), model.n_outputs(), theta.len());
    let c = model.coefficients(theta, &prep.inputs)?;
    let analytic = model.sensitivities();
    let mut x = x0.to_vec();
    let mut xn = vec![0.0; nx];
    let mut s = vec![0.0; nx * nth];
    let mut sn = vec![0.0; nx * nth];
    let mut y = vec![0.0; ny];
    let mut dy = vec![0.0; ny * nth];
    // ∂x/∂x₀ kept column by column (column m = direction e_m at k = 0).
    let n0 = if options.x0_sensitivity { nx } else { 0 };
    let mut s0: Vec<Vec<f64>> =
        (0..n0).map(|m| (0..nx).map(|i| f64::from(u8::from(i == m))).collect()).collect();
    let mut s0n = vec![0.0; nx];
    let mut col = vec![0.0; ny];
    let mut dy0 = vec![0.0; ny * n0];
    let mut live0 = options.x0_sensitivity;
    for k in 0..prep.n {
        model.output(&c, &prep.inputs, k, &x, &mut y);
        match analytic {
            Some(a) => a.output_sensitivity(&c, &prep.inputs, k, &x, &s, &mut dy),
            None => fd_sensitivity(model, prep, theta, fd_scale, &x, &s, &mut dy, ny, |c, xv, o| {
                model.output(c, &prep.inputs, k, xv, o)
            })?,
        }
        if !y.iter().chain(dy.iter()).all(|v| v.is_finite()) {
            return Err(diverged(model, prep, theta, k));
        }
        for (m, v) in s0.iter().enumerate() {
            if live0 {
                model.output_state_derivative(&c, &prep.inputs, k, &x, v, &mut col);
            } else {
                col.fill(0.0);
            }
            for i in 0..ny {
                dy0[i * n0 + m] = col[i];
            }
        }
        visit(k, &y, &dy, &dy0);
        if options.restarts_at(k) {
            x.copy_from_slice(prep.y_at(k, ny));
            s.fill(0.0);
            live0 = false;
        }
        if k + 1 < prep.n && nx > 0 {
            if live0 {
                for v in s0.iter_mut() {
                    model.step_state_derivative(&c, &prep.inputs, k, &x, v, &mut s0n);
                    v.copy_from_slice(&s0n);
                }
                // A stable model forgets its initial state: once ∂x/∂x₀ has decayed below
                // 1e-150 it is exactly zero for every later sum, and carrying it on into
                // subnormal numbers would only slow the pass down many times.
                if s0.iter().flatten().all(|v| v.abs() < 1e-150) {
                    live0 = false;
                }
            }
            match analytic {
                Some(a) => a.step_sensitivity(&c, &prep.inputs, k, &x, &s, &mut xn, &mut sn),
                None => {
                    model.step(&c, &prep.inputs, k, &x, &mut xn);
                    fd_sensitivity(model, prep, theta, fd_scale, &x, &s, &mut sn, nx, |c, xv, o| {
                        model.step(c, &prep.inputs, k, xv, o)
                    })?;
                }
            }
            if !xn.iter().chain(sn.iter()).all(|v| v.is_finite()) {
                return Err(diverged(model, prep, theta, k + 1));
            }
            std::mem::swap(&mut x, &mut xn);
            std::mem::swap(&mut s, &mut sn);
        }
    }
    Ok(())
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
    if prep.n < min || prep.y.len() != prep.n * ny {
        return bad(
            "prepared data",
            format!(
                "experiment `{}`: {} output values for {} samples of {ny} outputs (need N ≥ {min})",
                prep.name,
                prep.y.len(),
                prep.n
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

fn check_shooting<M: GreyBoxModel>(model: &M, horizon: Option<usize>) -> Result<()> {
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

/// Central-difference Jacobian of `g(x, θ)` with respect to `(x, θ/scale)`, rows = len(g).
fn fd_jacobian<G>(nx: usize, x: &[f64], theta: &[f64], scale: &[f64], g: G) -> Result<Vec<Vec<f64>>>
where
    G: Fn(&[f64], &[f64]) -> Result<Vec<f64>>,
{
    let nth = theta.len();
    // finitediff steps every variable by an absolute ∛ε: scale the states by their own size
    // (1 + |x_i|, as the directional differences) as θ is scaled by `scale`, so that a state
    // of 400 K or of 1e-6 A is differenced at the same relative precision.
    let x_scale: Vec<f64> = x.iter().map(|v| 1.0 + v.abs()).collect();
    let v0: Vec<f64> = x
        .iter()
        .zip(&x_scale)
        .map(|(v, s)| v / s)
        .chain(theta.iter().zip(scale).map(|(t, s)| t / s))
        .collect();
    let f = |v: &Vec<f64>| -> std::result::Result<Vec<f64>, argmin::core::Error> {
        let xs: Vec<f64> = (0..nx).map(|i| v[i] * x_scale[i]).collect();
        let th: Vec<f64> = (0..nth).map(|j| v[nx + j] * scale[j]).collect();
        Ok(g(&xs, &th)?)
    };
    let mut jac = finitediff::vec::central_jacobian(&f)(&v0).map_err(Error::from_argmin)?;
    for row in jac.iter_mut() {
        for (d, s) in row.iter_mut().zip(&x_scale) {
            *d /= s;
        }
    }
    Ok(jac)
}

/// Sensitivity of `g(x, θ)` from finite differences, chained with the state sensitivity:
/// `out = G_x s + G_θ` (row-major `n_out × n_θ`). `g` is the step (`n_out = n_x`) or the
/// output map (`n_out = n_y`), evaluated by `eval(coefficients, x, out)`.
#[allow(clippy::too_many_arguments)]
fn fd_sensitivity<M, G>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    scale: &[f64],
    x: &[f64],
    s: &[f64],
    out: &mut [f64],
    n_out: usize,
    eval: G,
) -> Result<()>
where
    M: GreyBoxModel,
    G: Fn(&M::Coefficients, &[f64], &mut [f64]),
{
    let nx = model.n_states();
    let jac = fd_jacobian(nx, x, theta, scale, |xv, th| {
        let c = model.coefficients(th, &prep.inputs)?;
        let mut o = vec![0.0; n_out];
        eval(&c, xv, &mut o);
        Ok(o)
    })?;
    chain(&jac, nx, s, scale, out);
    Ok(())
}

/// `out[i, j] = Σ_m jac[i][m] s[m, j] + jac[i][nx + j] / scale[j]`.
fn chain(jac: &[Vec<f64>], nx: usize, s: &[f64], scale: &[f64], out: &mut [f64]) {
    let nth = scale.len();
    for (i, row) in jac.iter().enumerate() {
        for j in 0..nth {
            let mut v = row[nx + j] / scale[j];
            for m in 0..nx {
                v += row[m] * s[m * nth + j];
            }
            out[i * nth + j] = v;
        }
    }
}
