//! One record simulated, with or without sensitivities: sample by sample, or in blocks
//! ([`super::simulate_blocks`]) when that is faster.

use super::blocks::simulate_blocks;
use super::checks::{SimOptions, check_inputs, check_shooting, diverged};
use crate::error::Result;
use crate::model::{GreyBoxModel, Prepared};

/// Simulated outputs `ŷ`, row-major `N × n_y`.
///
/// # Errors
/// Those of [`GreyBoxModel::coefficients`] for an invalid θ;
/// [`crate::Error::SimulationDiverged`] naming the experiment, the sample and θ when the state
/// stops being finite; [`crate::Error::InvalidOption`] for θ not of length n_θ, an `x0` not of
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
/// As [`simulate`]; [`crate::Error::InvalidOption`] for `fd_scale` of the wrong length.
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
