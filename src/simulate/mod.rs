//! Simulation of a [`GreyBoxModel`]: single shooting from the measured first state, with
//! forward sensitivities, streamed sample by sample.
//!
//! [`simulate`] returns the predicted outputs; [`visit_sensitivities`] calls a closure with
//! `ŷ_k` and `∂ŷ_k/∂θ` at every sample, so that an estimator can accumulate the normal
//! equations `JᵀJ`, `Jᵀε` in one pass without ever storing the `N n_y × n_θ` Jacobian.
//! Models without analytic sensitivities get them from central finite differences of
//! their step (crate `finitediff`), with steps relative to each parameter's scale.
//!
//! Source: forward sensitivity analysis of a discrete recursion, e.g. Ljung, *System
//! Identification* (2nd ed.), section 10.3; thesis section 5.3 (Tenerz 2011).

use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Prepared, describe};

/// How the simulation is restarted from measured data (prediction criteria).
///
/// `horizon = None` is pure simulation (output error) from the measured first state;
/// `Some(k)` restarts the state from the measured output every k samples
/// (k-step-ahead prediction; `k = 1` is one-step-ahead prediction, i.e. equation error). Restarting needs a model whose
/// state is its output (`n_x = n_y`, output = state), as the PMSM models.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Shooting {
    /// Restart period in samples; `None` = simulate the whole record.
    pub horizon: Option<usize>,
}

impl Shooting {
    /// Whether the state is reset to the measurement after the output at sample k.
    pub(crate) fn restarts_at(&self, k: usize) -> bool {
        matches!(self.horizon, Some(h) if k.is_multiple_of(h))
    }
}

/// Simulated outputs `ŷ`, row-major `N × n_y`, from the experiment's first state.
///
/// # Errors
/// Those of [`GreyBoxModel::coefficients`] for an invalid θ, and
/// [`Error::SimulationDiverged`] naming the experiment, the sample and θ when the state
/// stops being finite.
pub fn simulate<M: GreyBoxModel>(model: &M, prep: &Prepared<M::Inputs>, theta: &[f64]) -> Result<Vec<f64>> {
    simulate_with(model, prep, theta, Shooting::default())
}

/// As [`simulate`], with restarts from the measurement every `shooting.horizon` samples.
///
/// # Errors
/// As [`simulate`]; [`Error::InvalidOption`] for a zero horizon or a model whose state is
/// not its output.
pub fn simulate_with<M: GreyBoxModel>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    shooting: Shooting,
) -> Result<Vec<f64>> {
    simulate_from(model, prep, theta, &prep.x0, shooting)
}

/// As [`simulate_with`], from the initial state `x0` (length n_x) instead of the measured one.
///
/// # Errors
/// As [`simulate_with`]; [`Error::InvalidOption`] for θ not of length n_θ, `x0` not of
/// length n_x, or prepared data of inconsistent shape.
pub fn simulate_from<M: GreyBoxModel>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    x0: &[f64],
    shooting: Shooting,
) -> Result<Vec<f64>> {
    check_shooting(model, shooting)?;
    check_inputs(model, prep, theta, x0)?;
    let (nx, ny) = (model.n_states(), model.n_outputs());
    let c = model.coefficients(theta, &prep.inputs)?;
    let mut yhat = vec![0.0; prep.n * ny];
    let mut x = x0.to_vec();
    let mut xn = vec![0.0; nx];
    for k in 0..prep.n {
        model.output(&c, &prep.inputs, k, &x, &mut yhat[k * ny..(k + 1) * ny]);
        if shooting.restarts_at(k) {
            x.copy_from_slice(prep.y_at(k, ny));
        }
        if k + 1 < prep.n {
            model.step(&c, &prep.inputs, k, &x, &mut xn);
            if !xn.iter().all(|v| v.is_finite()) {
                return Err(diverged(model, prep, theta, k + 1));
            }
            std::mem::swap(&mut x, &mut xn);
        }
    }
    Ok(yhat)
}

/// Calls `visit(k, ŷ_k, ∂ŷ_k/∂θ)` for every sample `k = 0..N`, with `ŷ_k` of length n_y
/// and `∂ŷ_k/∂θ` row-major `n_y × n_θ`.
///
/// `fd_scale` (length n_θ, positive) is each parameter's scale; it sets the
/// finite-difference step (`∛ε × scale`) for models without analytic sensitivities and is
/// ignored otherwise. The state and its sensitivity start at the measured first state
/// (sensitivity zero) and restart likewise every `shooting.horizon` samples.
///
/// # Errors
/// As [`simulate_with`].
pub fn visit_sensitivities<M, F>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    fd_scale: &[f64],
    shooting: Shooting,
    mut visit: F,
) -> Result<()>
where
    M: GreyBoxModel,
    F: FnMut(usize, &[f64], &[f64]),
{
    visit_sensitivities_from(model, prep, theta, &prep.x0, false, fd_scale, shooting, |k, y, dy, _| {
        visit(k, y, dy)
    })
}

/// As [`visit_sensitivities`], from the initial state `x0` (length n_x), and, when
/// `x0_sensitivity` is true, also with `∂ŷ_k/∂x₀` (row-major `n_y × n_x`, the fourth
/// argument of `visit`; empty otherwise). After a restart (k-step prediction) the state no
/// longer depends on x₀ and that sensitivity is zero.
///
/// # Errors
/// As [`simulate_with`]; [`Error::InvalidOption`] for `x0` of the wrong length.
#[allow(clippy::too_many_arguments)]
pub fn visit_sensitivities_from<M, F>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    x0: &[f64],
    x0_sensitivity: bool,
    fd_scale: &[f64],
    shooting: Shooting,
    mut visit: F,
) -> Result<()>
where
    M: GreyBoxModel,
    F: FnMut(usize, &[f64], &[f64], &[f64]),
{
    check_shooting(model, shooting)?;
    check_inputs(model, prep, theta, x0)?;
    if fd_scale.len() != theta.len() {
        return Err(Error::InvalidOption {
            option: "fd_scale".into(),
            reason: format!("{} scales for {} parameters", fd_scale.len(), theta.len()),
        });
    }
    let (nx, ny, nth) = (model.n_states(), model.n_outputs(), theta.len());
    let c = model.coefficients(theta, &prep.inputs)?;
    let analytic = model.has_sensitivities();
    let mut x = x0.to_vec();
    let mut xn = vec![0.0; nx];
    let mut s = vec![0.0; nx * nth];
    let mut sn = vec![0.0; nx * nth];
    let mut y = vec![0.0; ny];
    let mut dy = vec![0.0; ny * nth];
    // ∂x/∂x₀ kept column by column (column m = direction e_m at k = 0).
    let n0 = if x0_sensitivity { nx } else { 0 };
    let mut s0: Vec<Vec<f64>> =
        (0..n0).map(|m| (0..nx).map(|i| f64::from(u8::from(i == m))).collect()).collect();
    let mut s0n = vec![0.0; nx];
    let mut col = vec![0.0; ny];
    let mut dy0 = vec![0.0; ny * n0];
    let mut live0 = x0_sensitivity;
    for k in 0..prep.n {
        model.output(&c, &prep.inputs, k, &x, &mut y);
        if analytic {
            model.output_sensitivity(&c, &prep.inputs, k, &x, &s, &mut dy);
        } else {
            fd_sensitivity(model, prep, theta, fd_scale, &x, &s, &mut dy, ny, |c, xv, o| {
                model.output(c, &prep.inputs, k, xv, o)
            })?;
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
        if shooting.restarts_at(k) {
            x.copy_from_slice(prep.y_at(k, ny));
            s.fill(0.0);
            live0 = false;
        }
        if k + 1 < prep.n {
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
            if analytic {
                model.step_sensitivity(&c, &prep.inputs, k, &x, &s, &mut xn, &mut sn);
            } else {
                model.step(&c, &prep.inputs, k, &x, &mut xn);
                fd_sensitivity(model, prep, theta, fd_scale, &x, &s, &mut sn, nx, |c, xv, o| {
                    model.step(c, &prep.inputs, k, xv, o)
                })?;
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
    if prep.n < 2 || prep.y.len() != prep.n * ny {
        return bad(
            "prepared data",
            format!(
                "experiment `{}`: {} output values for {} samples of {ny} outputs (need N ≥ 2)",
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

fn check_shooting<M: GreyBoxModel>(model: &M, shooting: Shooting) -> Result<()> {
    match shooting.horizon {
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
    let v0: Vec<f64> = x.iter().copied().chain(theta.iter().zip(scale).map(|(t, s)| t / s)).collect();
    let f = |v: &Vec<f64>| -> std::result::Result<Vec<f64>, argmin::core::Error> {
        let th: Vec<f64> = (0..nth).map(|j| v[nx + j] * scale[j]).collect();
        Ok(g(&v[..nx], &th)?)
    };
    finitediff::vec::central_jacobian(&f)(&v0).map_err(Error::from_argmin)
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
