//! Finite-difference sensitivities for models without analytic ones (crate `finitediff`,
//! central differences with steps relative to each parameter's and state's scale).

use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Prepared};

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
pub(crate) fn fd_sensitivity<M, G>(
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
