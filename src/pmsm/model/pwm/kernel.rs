//! The block kernel of [`PmsmPwm`] whose predictor restarts every period from the measured
//! current (`k_o` held at 1, the default): each period's step then depends on the measured
//! current at its start only, so the periods of a block are stepped in parallel, and the
//! numbers are the per-sample step's to the bit, for any number of threads.

use super::model::{PmsmPwm, PwmCoefficients, PwmInputs};
use crate::model::{BLOCK_LEN, Block, BlockContext, BlockKernel, GreyBoxModel, SimState};
use crate::pmsm::model::pwm::dual::{Dual, Scalar};
use crate::pmsm::model::pwm::period;
use rayon::prelude::*;

/// Periods one parallel task steps: a few hundred microseconds of work with
/// sensitivities, tens without, against a few microseconds to hand a task out.
const TASK: usize = 64;

impl BlockKernel<PwmInputs, PwmCoefficients> for PmsmPwm {
    fn run(
        &self,
        c: &PwmCoefficients,
        inp: &PwmInputs,
        ctx: &BlockContext<'_>,
        st: &mut SimState,
        b: &mut Block,
    ) {
        let (k0, len, sens) = (b.k0, b.len, b.sensitivities);
        let m = if sens { c.nth } else { 0 };
        // Per period: the next state, then its sensitivities row by row.
        let stride = 2 + 2 * m;
        let steps = len.min(ctx.n.saturating_sub(k0 + 1));
        let SimState { x, s, s0, live0, scratch, .. } = st;
        scratch.resize(stride * len, 0.0);
        let q = sens.then(|| self.params(&c.theta, Dual::seed));
        scratch[..stride * steps].par_chunks_mut(stride * TASK).enumerate().for_each(|(task, out)| {
            for (j, o) in out.chunks_mut(stride).enumerate() {
                let k = k0 + task * TASK + j;
                let (y, per) = ([inp.i_d[k], inp.i_q[k]], &inp.periods[k]);
                match &q {
                    Some(q) => {
                        let xn = period::step_dual(q, per, y.map(Dual::cst));
                        o[0] = xn[0].v;
                        o[1] = xn[1].v;
                        o[2..2 + m].copy_from_slice(&xn[0].d[..m]);
                        o[2 + m..].copy_from_slice(&xn[1].d[..m]);
                    }
                    None => o[..2].copy_from_slice(&period::step(&c.q, per, y)),
                }
            }
        });
        // In order: the outputs, the restarts and the initial state's directions as the
        // per-sample runner has them (`simulate::blocks`), then the state from the steps.
        let n0 = b.n_x0();
        let (yb, dyb, dy0b) = b.channels_mut();
        let (mut v, mut vn, mut col) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        for t in 0..len {
            let k = k0 + t;
            yb[t] = x[0];
            yb[BLOCK_LEN + t] = x[1];
            if sens {
                for (ch, sv) in s.iter().enumerate() {
                    dyb[ch * BLOCK_LEN + t] = *sv;
                }
                for mm in 0..n0 {
                    if *live0 {
                        (0..2).for_each(|i| v[i] = s0[i * 2 + mm]);
                        self.output_state_derivative(c, inp, k, x, &v, &mut col);
                    } else {
                        col = [0.0; 2];
                    }
                    for i in 0..2 {
                        dy0b[(i * n0 + mm) * BLOCK_LEN + t] = col[i];
                    }
                }
            }
            if ctx.restarts_at(k) {
                for (xi, y) in x.iter_mut().zip(ctx.measured) {
                    *xi = y[k];
                }
                s.fill(0.0);
                s0.fill(0.0);
                *live0 = false;
            }
            if t < steps {
                if sens && *live0 {
                    for mm in 0..2 {
                        (0..2).for_each(|i| v[i] = s0[i * 2 + mm]);
                        self.step_state_derivative(c, inp, k, x, &v, &mut vn);
                        (0..2).for_each(|i| s0[i * 2 + mm] = vn[i]);
                    }
                    if s0.iter().all(|v| v.abs() < 1e-150) {
                        s0.fill(0.0);
                        *live0 = false;
                    }
                }
                let o = &scratch[t * stride..(t + 1) * stride];
                x.copy_from_slice(&o[..2]);
                if sens {
                    s.copy_from_slice(&o[2..]);
                }
            }
        }
        st.k = k0 + len;
    }
}
