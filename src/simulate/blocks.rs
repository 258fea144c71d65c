//! The blocked simulation: [`simulate_blocks`] runs a model over a record
//! [`BLOCK_LEN`] samples at a time, through the model's [`BlockKernel`](crate::model::BlockKernel) when it has one
//! and sample by sample (analytic or finite-difference sensitivities) otherwise.

use super::fd::fd_sensitivity;
use super::{SimOptions, check_inputs, check_shooting, diverged};
use crate::error::{Error, Result};
use crate::model::{BLOCK_LEN, Block, BlockContext, GreyBoxModel, Prepared, SimState};

/// Runs the model over the record and calls `f` with each [`Block`] in order: the outputs
/// `ŷ` and, with `sensitivities`, `∂ŷ/∂θ` and (with `options.x0_sensitivity`) `∂ŷ/∂x₀`,
/// with the restarts of `options.horizon` (see [`super::visit_sensitivities`] for the
/// semantics). The estimator's passes are sums over these blocks.
///
/// # Errors
/// As [`super::simulate`]; [`Error::InvalidOption`] for `fd_scale` of the wrong length;
/// [`Error::SimulationDiverged`] at the first sample with a non-finite output or
/// sensitivity; whatever `f` returns.
pub fn simulate_blocks<M, F>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    options: &SimOptions<'_>,
    sensitivities: bool,
    mut f: F,
) -> Result<()>
where
    M: GreyBoxModel,
    F: FnMut(&Block) -> Result<()>,
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
    let x0_sens = sensitivities && options.x0_sensitivity;
    let mut state = SimState::new(x0, nth, x0_sens);
    let mut block = Block::new(ny, nth, if x0_sens { nx } else { 0 }, sensitivities);
    let ctx = BlockContext { n: prep.n, horizon: options.horizon, measured: &prep.y };
    let kernel = model.block_kernel();
    let mut generic = PerSample::new(model, theta, fd_scale);
    while state.k < prep.n {
        block.k0 = state.k;
        block.len = BLOCK_LEN.min(prep.n - state.k);
        match kernel {
            Some(kern) => kern.run(&c, &prep.inputs, &ctx, &mut state, &mut block),
            None => generic.run(prep, &c, &ctx, &mut state, &mut block)?,
        }
        // A kernel whose non-finite values persist shows them in its end state.
        let persists = kernel.is_some_and(|k| k.non_finite_persists()) && options.horizon.is_none();
        let suspect = !persists || !state.is_finite();
        if suspect && let Some(t) = block.first_non_finite() {
            return Err(diverged(model, prep, theta, block.k0 + t));
        }
        f(&block)?;
    }
    Ok(())
}

/// A function of the coefficients and a state into an output slice (a step or an output
/// map), for finite differences.
type Eval<'e, C> = dyn Fn(&C, &[f64], &mut [f64]) + 'e;

/// The per-sample runner: the model's `step`/`output` with its analytic sensitivities or
/// finite differences, and the state derivatives for `∂x/∂x₀`.
struct PerSample<'a, M: GreyBoxModel> {
    model: &'a M,
    theta: &'a [f64],
    fd_scale: &'a [f64],
    xn: Vec<f64>,
    sn: Vec<f64>,
    y: Vec<f64>,
    dy: Vec<f64>,
    v: Vec<f64>,
    vn: Vec<f64>,
    col: Vec<f64>,
}

impl<'a, M: GreyBoxModel> PerSample<'a, M> {
    fn new(model: &'a M, theta: &'a [f64], fd_scale: &'a [f64]) -> Self {
        let (nx, ny, nth) = (model.n_states(), model.n_outputs(), theta.len());
        Self {
            model,
            theta,
            fd_scale,
            xn: vec![0.0; nx],
            sn: vec![0.0; nx * nth],
            y: vec![0.0; ny],
            dy: vec![0.0; ny * nth],
            v: vec![0.0; nx],
            vn: vec![0.0; nx],
            col: vec![0.0; ny],
        }
    }

    fn run(
        &mut self,
        prep: &Prepared<M::Inputs>,
        c: &M::Coefficients,
        ctx: &BlockContext<'_>,
        st: &mut SimState,
        b: &mut Block,
    ) -> Result<()> {
        let model = self.model;
        let (nx, ny, n0) = (model.n_states(), model.n_outputs(), b.n_x0());
        let sens = b.sensitivities;
        let analytic = model.sensitivities();
        let inp = &prep.inputs;
        let (theta, fd_scale) = (self.theta, self.fd_scale);
        // Finite differences of `eval` (the output map or the step), chained with `s`.
        let fd = |x: &[f64], s: &[f64], out: &mut [f64], n_out, eval: &Eval<'_, M::Coefficients>| {
            fd_sensitivity(model, prep, theta, fd_scale, x, s, out, n_out, eval)
        };
        for t in 0..b.len {
            let k = b.k0 + t;
            let (yb, dyb, dy0b) = b.channels_mut();
            model.output(c, inp, k, &st.x, &mut self.y);
            for i in 0..ny {
                yb[i * BLOCK_LEN + t] = self.y[i];
            }
            if sens {
                match analytic {
                    Some(a) => a.output_sensitivity(c, inp, k, &st.x, &st.s, &mut self.dy),
                    None => fd(&st.x, &st.s, &mut self.dy, ny, &|c, xv, o| model.output(c, inp, k, xv, o))?,
                }
                for (ch, v) in self.dy.iter().enumerate() {
                    dyb[ch * BLOCK_LEN + t] = *v;
                }
                for m in 0..n0 {
                    if st.live0 {
                        (0..nx).for_each(|i| self.v[i] = st.s0[i * nx + m]);
                        model.output_state_derivative(c, inp, k, &st.x, &self.v, &mut self.col);
                    } else {
                        self.col.fill(0.0);
                    }
                    for i in 0..ny {
                        dy0b[(i * n0 + m) * BLOCK_LEN + t] = self.col[i];
                    }
                }
            }
            if ctx.restarts_at(k) {
                for (x, c) in st.x.iter_mut().zip(ctx.measured) {
                    *x = c[k];
                }
                st.s.fill(0.0);
                st.s0.fill(0.0);
                st.live0 = false;
            }
            if k + 1 < ctx.n && nx > 0 {
                if sens && st.live0 {
                    for m in 0..nx {
                        (0..nx).for_each(|i| self.v[i] = st.s0[i * nx + m]);
                        model.step_state_derivative(c, inp, k, &st.x, &self.v, &mut self.vn);
                        (0..nx).for_each(|i| st.s0[i * nx + m] = self.vn[i]);
                    }
                    // A stable model forgets its initial state: once ∂x/∂x₀ has decayed
                    // below 1e-150 it is exactly zero for every later sum, and carrying it
                    // on into subnormal numbers would only slow the pass down many times.
                    if st.s0.iter().all(|v| v.abs() < 1e-150) {
                        st.s0.fill(0.0);
                        st.live0 = false;
                    }
                }
                match (sens, analytic) {
                    (true, Some(a)) => {
                        a.step_sensitivity(c, inp, k, &st.x, &st.s, &mut self.xn, &mut self.sn)
                    }
                    (true, None) => {
                        model.step(c, inp, k, &st.x, &mut self.xn);
                        fd(&st.x, &st.s, &mut self.sn, nx, &|c, xv, o| model.step(c, inp, k, xv, o))?;
                    }
                    (false, _) => model.step(c, inp, k, &st.x, &mut self.xn),
                }
                std::mem::swap(&mut st.x, &mut self.xn);
                if sens {
                    std::mem::swap(&mut st.s, &mut self.sn);
                }
            }
        }
        st.k = b.k0 + b.len;
        Ok(())
    }
}
