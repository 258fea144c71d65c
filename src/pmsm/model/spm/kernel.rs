//! The SPM step's per-interval terms and the whole-block kernel: the per-sample step, its
//! sensitivities and the kernel share the terms, so the three agree to the last bit.
//!
//! Over interval k (module docs of [`super`]; MODEL.md §4, thesis 5.2) with
//! `z = R_s + j ω_e L_s`, `a = e^{−j ω_e h} e^{−R_s h/L_s}`, `b = (1 − a)/z`,
//! `e = K_e √(2/3) ω_m`:
//!
//! ```text
//! i[k+1] = a i[k] + f,   f = b (u − j e) (dq hold),  u g − b j e (stator hold)
//! ∂i[k+1]/∂θ = a ∂i[k]/∂θ + (∂a/∂θ) i[k] + ∂f/∂θ
//! ```
//!
//! with `∂a/∂R_s = −(h/L) a`, `∂a/∂L_s = (R_s h/L²) a`, `∂b/∂R_s = ((h/L) a − b)/z`,
//! `∂b/∂L_s = (−(R_s h/L²) a − j ω_e b)/z`, `g = (1 − e^{−R_s h/L})/R_s`.

use super::super::interval::half_angle_rotation;
use super::super::interval::{C64, IntervalData, IntervalVoltage, SQRT_2_3, VoltageHold};
use super::{PmsmSpm, SpmCoefficients, SpmInputs};
use crate::model::{BLOCK_LEN, Block, BlockContext, BlockKernel, SimState};
use multiversion::multiversion;

/// The terms of interval k: the step `i[k+1] = a i[k] + forced`, and with sensitivities
/// the derivatives of the forced term by `r_s`, `l_s`, `k_e` and `v_dt` (zero when not
/// computed).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Terms {
    pub a: C64,
    pub forced: C64,
    pub f_r: C64,
    pub f_l: C64,
    pub f_k: C64,
    pub f_v: C64,
}

/// `b · j e`.
#[inline(always)]
fn times_j(b: C64, e: f64) -> C64 {
    C64::new(-b.im * e, b.re * e)
}

/// The θ- and speed-dependent core of interval k's step: `ω_e`, `√(2/3) ω_m`, `a`, `1/z`,
/// `b = (1 − a)/z` and `e = K_e √(2/3) ω_m`.
pub(super) struct Core {
    pub w: f64,
    pub emf: f64,
    pub a: C64,
    pub z_inv: C64,
    pub b: C64,
    pub e: f64,
}

/// The [`Core`] at `half = [sin φ/2, cos φ/2]` and mean mechanical speed `w_m`.
#[inline(always)]
pub(super) fn core(c: &SpmCoefficients, n_p: f64, [s, co]: [f64; 2], w_m: f64) -> Core {
    let (rot, vers) = half_angle_rotation(s, co);
    let (w, emf) = (n_p * w_m, SQRT_2_3 * w_m);
    let a = rot * c.d;
    let wl = w * c.l;
    let q = 1.0 / (c.r * c.r + wl * wl);
    let z_inv = C64::new(c.r * q, -wl * q);
    // 1 − a = (1 − d) cos φ + (1 − cos φ) + j d sin φ, free of cancellation.
    let one_minus_a = C64::new(c.one_minus_d * rot.re + vers, -c.d * rot.im);
    let b = one_minus_a * z_inv;
    Core { w, emf, a, z_inv, b, e: c.k_e * emf }
}

/// The terms of one interval from its data as [`SpmInputs`] keeps it (`half = [sin φ/2,
/// cos φ/2]`, the mean mechanical speed `w_m`, the voltage term `u` and the inverter's
/// direction `dt`; `n_p` the pole pairs) for the hold (`stator`) and inverter model
/// (`v_dt`: n_θ = 4). The rotation `e^{−jφ}`, the versine `1 − cos φ`, `ω_e = n_p ω_m` and
/// `√(2/3) ω_m` are formed here, the one place both the per-sample step and the block
/// kernel take them from.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn terms_at<const SENS: bool>(
    c: &SpmCoefficients,
    stator: bool,
    v_dt: bool,
    n_p: f64,
    [s, co]: [f64; 2],
    w_m: f64,
    u: C64,
    dt: C64,
) -> Terms {
    let Core { w, emf, a, z_inv, b, e } = core(c, n_p, [s, co], w_m);
    let u = if v_dt { u + dt * c.v_dt } else { u };
    let forced = if stator { u * c.g - times_j(b, e) } else { b * C64::new(u.re, u.im - e) };
    if !SENS {
        return Terms { a, forced, ..Terms::default() };
    }
    let b_r = (a * (-c.a_r) - b) * z_inv;
    let b_l = (a * (-c.a_l) - times_j(b, w)) * z_inv;
    let (f_r, f_l) = if stator {
        (u * c.g_r - times_j(b_r, e), u * c.g_l - times_j(b_l, e))
    } else {
        let ue = C64::new(u.re, u.im - e);
        (b_r * ue, b_l * ue)
    };
    let f_k = -times_j(b, emf);
    let f_v = match (v_dt, stator) {
        (false, _) => C64::default(),
        (true, true) => dt * c.g,
        (true, false) => b * dt,
    };
    Terms { a, forced, f_r, f_l, f_k, f_v }
}

/// The terms of interval k (see [`terms_at`]).
#[inline(always)]
fn terms_for<const SENS: bool>(
    c: &SpmCoefficients,
    inp: &SpmInputs,
    stator: bool,
    v_dt: bool,
    k: usize,
) -> Terms {
    let dt = if v_dt { inp.dt[k] } else { C64::default() };
    let hold = if stator { VoltageHold::Stator } else { VoltageHold::Dq };
    let (half, w_m, u) = inp.source.interval(hold, k);
    terms_at::<SENS>(c, stator, v_dt, inp.source.n_p, half, w_m, u, dt)
}

/// [`terms_for`] with the model's hold and parameter count.
#[inline(always)]
pub(super) fn terms<const SENS: bool>(
    c: &SpmCoefficients,
    inp: &SpmInputs,
    hold: VoltageHold,
    k: usize,
) -> Terms {
    terms_for::<SENS>(c, inp, hold == VoltageHold::Stator, c.nth == 4, k)
}

impl BlockKernel<SpmInputs, SpmCoefficients> for PmsmSpm {
    fn run(
        &self,
        c: &SpmCoefficients,
        inp: &SpmInputs,
        ctx: &BlockContext<'_>,
        st: &mut SimState,
        b: &mut Block,
    ) {
        let stator = self.setup.hold == VoltageHold::Stator;
        run_any(c, inp, ctx, st, b, (b.sensitivities, stator, c.nth == 4));
    }

    /// The state is the output and the step a sum of products: a NaN or ∞ in any output or
    /// sensitivity stays in the state (0 · ∞ is NaN).
    fn non_finite_persists(&self) -> bool {
        true
    }
}

/// Calls `$f::<SENS, STATOR, VDT>($args)` for the run-time mode `(sensitivities, stator
/// hold, v_dt)`: one monomorphised loop per mode.
macro_rules! by_mode {
    ($f:ident, $mode:expr, $($arg:expr),*) => {
        match $mode {
            (false, false, false) => $f::<false, false, false>($($arg),*),
            (false, false, true) => $f::<false, false, true>($($arg),*),
            (false, true, false) => $f::<false, true, false>($($arg),*),
            (false, true, true) => $f::<false, true, true>($($arg),*),
            (true, false, false) => $f::<true, false, false>($($arg),*),
            (true, false, true) => $f::<true, false, true>($($arg),*),
            (true, true, false) => $f::<true, true, false>($($arg),*),
            (true, true, true) => $f::<true, true, true>($($arg),*),
        }
    };
}

/// Number of per-interval term arrays a block keeps: `a`, the forced term and its
/// derivatives by `r_s`, `l_s`, `k_e`, `v_dt`, each as real and imaginary parts.
const TERM_ARRAYS: usize = 12;

/// Number of per-interval data arrays behind them ([`IntervalData`]).
const INTERVAL_ARRAYS: usize = 5;

/// The terms of intervals `k0 .. k0 + steps` as arrays (`out`: [`TERM_ARRAYS`] channels
/// of [`BLOCK_LEN`], then the [`INTERVAL_ARRAYS`] of their data): every interval independent of the others, so the loop vectorises;
/// compiled for AVX-512 and AVX2 as well as the baseline and chosen at run time. The
/// arithmetic is [`terms_at`]'s, so the numbers are the per-sample step's to the bit.
#[multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn fill_terms(
    c: &SpmCoefficients,
    inp: &SpmInputs,
    k0: usize,
    steps: usize,
    mode: (bool, bool, bool),
    out: &mut [f64],
) {
    by_mode!(fill, mode, c, inp, k0, steps, out)
}

#[inline(always)]
fn fill<const SENS: bool, const STATOR: bool, const VDT: bool>(
    c: &SpmCoefficients,
    inp: &SpmInputs,
    k0: usize,
    steps: usize,
    out: &mut [f64],
) {
    let (out, data) = out.split_at_mut(TERM_ARRAYS * BLOCK_LEN);
    let mut ch = data.chunks_exact_mut(BLOCK_LEN).map(|c| &mut c[..steps]);
    let mut next = || ch.next().unwrap_or_default();
    let iv = IntervalData { w_m: next(), sin: next(), cos: next(), u_re: next(), u_im: next() };
    inp.source.fill_intervals(STATOR, k0, iv);
    let (w_m, s, co) =
        (&data[..BLOCK_LEN], &data[BLOCK_LEN..2 * BLOCK_LEN], &data[2 * BLOCK_LEN..3 * BLOCK_LEN]);
    let (u_re, u_im) = (&data[3 * BLOCK_LEN..4 * BLOCK_LEN], &data[4 * BLOCK_LEN..5 * BLOCK_LEN]);
    let dt = if VDT { &inp.dt[k0..k0 + steps] } else { &[][..] };
    let mut ch = out.chunks_exact_mut(BLOCK_LEN);
    let mut next = || ch.next().map(|c| &mut c[..steps]).unwrap_or_default();
    let (a_re, a_im, f_re, f_im) = (next(), next(), next(), next());
    let (r_re, r_im, l_re, l_im, k_re, k_im, v_re, v_im) =
        (next(), next(), next(), next(), next(), next(), next(), next());
    for t in 0..steps {
        let d = if VDT { dt[t] } else { C64::default() };
        let u = C64::new(u_re[t], u_im[t]);
        let tm = terms_at::<SENS>(c, STATOR, VDT, inp.source.n_p, [s[t], co[t]], w_m[t], u, d);
        a_re[t] = tm.a.re;
        a_im[t] = tm.a.im;
        f_re[t] = tm.forced.re;
        f_im[t] = tm.forced.im;
        if SENS {
            r_re[t] = tm.f_r.re;
            r_im[t] = tm.f_r.im;
            l_re[t] = tm.f_l.re;
            l_im[t] = tm.f_l.im;
            k_re[t] = tm.f_k.re;
            k_im[t] = tm.f_k.im;
            if VDT {
                v_re[t] = tm.f_v.re;
                v_im[t] = tm.f_v.im;
            }
        }
    }
}

/// [`run_block`] for the mode `(sensitivities, stator hold, v_dt)`, compiled for AVX2 as
/// well as the baseline (three-operand instructions: fewer register moves; no FMA, so the
/// numbers are the same) and chosen at run time.
#[multiversion(targets("x86_64+avx2"))]
fn run_any<'a>(
    c: &SpmCoefficients,
    inp: &SpmInputs,
    ctx: &BlockContext<'a>,
    st: &mut SimState,
    b: &mut Block,
    mode: (bool, bool, bool),
) {
    by_mode!(run_block, mode, c, inp, ctx, st, b)
}

/// One block of the SPM recursion, monomorphised per sensitivities, hold and inverter
/// model; every channel is a `[f64; BLOCK_LEN]` and the parameters are written out, so the
/// loop carries no bounds checks and keeps the sensitivities in registers. `∂i/∂x₀` is carried as one complex product `P = Π a` (`∂i/∂i_d0 = P`,
/// `∂i/∂i_q0 = j P`).
#[inline(always)]
fn run_block<const SENS: bool, const STATOR: bool, const VDT: bool>(
    c: &SpmCoefficients,
    inp: &SpmInputs,
    ctx: &BlockContext<'_>,
    st: &mut SimState,
    b: &mut Block,
) {
    let (k0, len) = (b.k0, b.len.min(BLOCK_LEN));
    let m = c.nth;
    let n0 = b.n_x0();
    // The shapes `BlockKernel::run` asks of its caller: otherwise the block and the state
    // turn non-finite, which the caller reports, rather than a panic or a wrong number.
    let shapes = k0 < ctx.n
        && inp.source.covers(ctx.n)
        && (!VDT || inp.dt.len() + 1 >= ctx.n)
        && b.n_outputs() == 2
        && st.x.len() == 2
        && (!SENS || (b.n_theta() == m && st.s.len() == 2 * m))
        && (n0 == 0 || (n0 == 2 && st.s0.len() == 4))
        && (ctx.horizon.is_none()
            || ctx.measured.iter().take(2).all(|c| c.len() == ctx.n) && ctx.measured.len() >= 2);
    if !shapes {
        let (yb, dyb, dy0b) = b.channels_mut();
        [yb, dyb, dy0b].into_iter().for_each(|c| c.fill(f64::NAN));
        st.x.fill(f64::NAN);
        st.k = k0 + len;
        return;
    }
    let mut i = C64::new(st.x[0], st.x[1]);
    let mut s = [C64::default(); 4];
    if SENS {
        for (j, sj) in s.iter_mut().enumerate().take(m) {
            *sj = C64::new(st.s[j], st.s[m + j]);
        }
    }
    let mut live0 = SENS && n0 == 2 && st.live0;
    let mut p = if live0 { C64::new(st.s0[0], st.s0[2]) } else { C64::default() };
    let mut next_restart = match ctx.horizon {
        Some(h) => k0.div_ceil(h) * h,
        None => usize::MAX,
    };
    let h = ctx.horizon.unwrap_or(usize::MAX);
    // Intervals in this block (the record's last sample has none).
    let steps = len.min(ctx.n - 1 - k0);
    let (yb, dyb, dy0b) = b.channels_mut();
    // The terms stored by the fill and loaded by the loop, apart from the data the fill
    // loads and the outputs the loop stores.
    let at_k0 = |v: &[f64]| v.get(k0..).map_or(0, |v| v.as_ptr() as usize);
    let complex_at_k0 = |v: &[C64]| v.get(k0..).map_or(0, |v| v.as_ptr() as usize);
    let (w_m, u) = (at_k0(&inp.source.w_m), &inp.source.u);
    let (d, q) = match u {
        IntervalVoltage::Terminal(d, q) => (at_k0(d), at_k0(q)),
        IntervalVoltage::Start(u0) => (complex_at_k0(u0), w_m),
    };
    let dt = if VDT { complex_at_k0(&inp.dt) } else { w_m };
    let outputs = [yb.as_ptr(), dyb.as_ptr(), dy0b.as_ptr()].map(|p| p as usize);
    let hot = [outputs[0], outputs[1], outputs[2], w_m, d, q, dt];
    let scratch = st.scratch_apart((TERM_ARRAYS + INTERVAL_ARRAYS) * BLOCK_LEN, &hot);
    fill_terms(c, inp, k0, steps, (SENS, STATOR, VDT), scratch);
    // Every channel as an array of BLOCK_LEN, indexed below BLOCK_LEN: no bounds checks in
    // the loop.
    let (terms, _) = scratch.as_chunks::<BLOCK_LEN>();
    let (
        [y_re, y_im, ..],
        [tm_a_re, tm_a_im, f_re, f_im, r_re, r_im, l_re, l_im, k_re, k_im, v_re, v_im, ..],
    ) = (yb.as_chunks_mut::<BLOCK_LEN>().0, terms)
    else {
        // Not reached (the shapes are checked above, the scratch holds every term): were it,
        // the block and the state turn non-finite, as above.
        [yb, dyb, dy0b].into_iter().for_each(|c| c.fill(f64::NAN));
        st.x.fill(f64::NAN);
        st.k = k0 + len;
        return;
    };
    // ∂ŷ/∂θ: the m real parts, then the m imaginary ones (m = 3, or 4 with v_dt).
    let (dy, _) = dyb.as_chunks_mut::<BLOCK_LEN>();
    let (dy_re, dy_im) = dy.split_at_mut(dy.len() / 2);
    let (dy0, _) = dy0b.as_chunks_mut::<BLOCK_LEN>();
    let term = |re: &[f64; BLOCK_LEN], im: &[f64; BLOCK_LEN], t: usize| C64::new(re[t], im[t]);
    for t in 0..len {
        let k = k0 + t;
        y_re[t] = i.re;
        y_im[t] = i.im;
        if SENS {
            // Written out per parameter (not a loop over m): the sensitivities stay in registers.
            for j in 0..if VDT { 4 } else { 3 } {
                dy_re[j][t] = s[j].re;
                dy_im[j][t] = s[j].im;
            }
            if let [d0, d1, d2, d3] = dy0 {
                d0[t] = p.re;
                d1[t] = -p.im;
                d2[t] = p.im;
                d3[t] = p.re;
            }
        }
        if k == next_restart {
            i = C64::new(ctx.measured[0][k], ctx.measured[1][k]);
            s = [C64::default(); 4];
            p = C64::default();
            live0 = false;
            next_restart = next_restart.saturating_add(h);
        }
        if t < steps {
            let a = term(tm_a_re, tm_a_im, t);
            let ai = a * i;
            if SENS {
                s[0] = a * s[0] + ai * c.a_r + term(r_re, r_im, t);
                s[1] = a * s[1] + ai * c.a_l + term(l_re, l_im, t);
                s[2] = a * s[2] + term(k_re, k_im, t);
                if VDT {
                    s[3] = a * s[3] + term(v_re, v_im, t);
                }
                if live0 {
                    p = a * p;
                    // As the per-sample path: a decayed ∂i/∂x₀ is exactly zero from here on.
                    if p.re.abs() < 1e-150 && p.im.abs() < 1e-150 {
                        p = C64::default();
                        live0 = false;
                    }
                }
            }
            i = ai + term(f_re, f_im, t);
        }
    }
    st.x[0] = i.re;
    st.x[1] = i.im;
    if SENS {
        for (j, sj) in s.iter().enumerate().take(m) {
            st.s[j] = sj.re;
            st.s[m + j] = sj.im;
        }
        if n0 == 2 {
            st.s0.copy_from_slice(&[p.re, -p.im, p.im, p.re]);
            st.live0 = live0;
        }
    }
    st.k = k0 + len;
}

#[cfg(test)]
mod tests;
