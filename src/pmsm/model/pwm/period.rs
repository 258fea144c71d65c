//! One sample period of the switching-resolved model: the pieces of constant leg states
//! between the switching and blanking instants, each an exact step of the dq current
//! equations with the stator-fixed voltage of its piece (MODEL.md §2, §4).
//!
//! Over a piece of length τ the phase voltages are constant, so in dq the voltage rotates,
//! `v(s) = R(−ω_e s) v₀`. With `ẋ = A x + B v(s) + c` (`A` the current equations' matrix,
//! `B = diag(1/L_d, 1/L_q)`, `c = (0, −ω_e ψ_f/L_q)`), the rotating particular solution
//! `P v(s)` solves `A P + ω_e P J = −B` (J the quarter turn), the constant one is
//! `x_c = −A⁻¹ c`, and the exact step is
//!
//! ```text
//! x(τ) = e^{Aτ} (x₀ − P v₀ − x_c) + P R(−ω_e τ) v₀ + x_c,
//! e^{Aτ} = e^{μτ} (C(τ) I + S(τ) (A − μ I)),  μ = tr A / 2,  δ = μ² − det A,
//! ```
//!
//! `C = cos ντ, S = sin ντ / ν` for `δ = −ν² < 0`, `cosh`, `sinh` for `δ > 0`, their series
//! near 0 (Moler & Van Loan, SIAM Review 45(1), 2003, §2: the 2×2 case). In complex form
//! `P`'s rows `z₁ = p₁₁ + j p₁₂`, `z₂ = p₂₁ + j p₂₂` solve
//! `[[a₁₁ − jω, a₁₂], [a₂₁, a₂₂ − jω]] z = (−1/L_d, −j/L_q)`; at `L_d = L_q` this is
//! `P = I/R`, the stator-hold step of MODEL.md §4.
//!
//! The leg voltages follow motulator's converter (Hinkkanen et al.): a leg conducts its
//! commanded switch, or during blanking the diode the current's direction selects, leg
//! state `(1 − s(i_x))/2`; every leg loses `u_th s(i_x)` to the conducting device; `s` is
//! taken at each piece's start from the model's own current. `s` is the sign, or
//! `(2/π) atan(i/i_w)` for a leg-state function smoothed over `i_w` by parasitic
//! capacitances.

use super::dual::Scalar;
use super::modulator::HalfPlan;

/// The parameters of one step in the scalar of the pass.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params<T> {
    /// Series resistance R_s (+ cable, + r_on) \[Ω\].
    pub r: T,
    pub l_d: T,
    pub l_q: T,
    pub k_e: T,
    /// Dead time t_d \[s\].
    pub t_d: T,
    /// Device threshold voltage u_th \[V\].
    pub u_th: T,
    /// Width of the smooth leg state \[A\]; `None`: the sign.
    pub i_w: Option<T>,
}

/// What one sample period knows from the data.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Period {
    /// Electrical angle at the period's start \[rad\].
    pub theta: f64,
    /// Interval-mean electrical speed \[rad/s\].
    pub w_e: f64,
    /// `√(2/3)` × interval-mean mechanical speed \[rad/s\]: back-EMF per unit K_e.
    pub emf: f64,
    /// DC-link voltage over the period \[V\].
    pub u_dc: f64,
    /// The half carrier periods, `n` of them.
    pub halves: [HalfPlan; 2],
    pub n: u8,
    /// The smallest duty ratio's distance to 0 or 1 over the legs and halves \[1\]: a leg
    /// this close to a clamp switches for a pulse the counter's resolution or a driver's
    /// minimum pulse may drop (0 for a clamped leg).
    pub duty_margin: f64,
    /// Electrical acceleration `a_e` over the period \[rad/s²\] ([`super::acceleration`]).
    pub acc_e: f64,
    /// The back-EMF's rate per unit K_e, `√(2/3) a_m` \[rad/s²\] (0 with `acc_e` unless set).
    pub emf_rate: f64,
}

impl Period {
    /// The period starting at electrical angle `theta` \[rad\] at interval-mean electrical
    /// and mechanical speeds `w_e`, `w_m` \[rad/s\] and DC link `u_dc` \[V\], of the carrier's
    /// half periods `(plans, n)` ([`super::modulator::halves`]).
    pub(crate) fn new(
        theta: f64,
        w_e: f64,
        w_m: f64,
        u_dc: f64,
        (halves, n): ([HalfPlan; 2], usize),
    ) -> Self {
        let duty_margin = halves[..n]
            .iter()
            .flat_map(|h| h.t_sw.map(|t| if t.is_finite() { t.min(h.len - t) / h.len } else { 0.0 }))
            .fold(f64::INFINITY, f64::min);
        Self {
            theta,
            w_e,
            emf: crate::pmsm::model::interval::SQRT_2_3 * w_m,
            u_dc,
            halves,
            n: n as u8,
            duty_margin,
            acc_e: 0.0,
            emf_rate: 0.0,
        }
    }

    /// The period's length h \[s\]: its half carrier periods'.
    pub(crate) fn len(&self) -> f64 {
        self.halves[..usize::from(self.n)].iter().map(|p| p.len).sum()
    }
}

/// A complex number over the pass's scalar.
#[derive(Clone, Copy, Debug)]
struct Cx<T> {
    re: T,
    im: T,
}

impl<T: Scalar> Cx<T> {
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self { re: self.re * o.re - self.im * o.im, im: self.re * o.im + self.im * o.re }
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let n = o.re * o.re + o.im * o.im;
        Self { re: (self.re * o.re + self.im * o.im) / n, im: (self.im * o.re - self.re * o.im) / n }
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self { re: self.re - o.re, im: self.im - o.im }
    }
}

/// The period's matrices: `A`, `μ`, `δ`, `P` and `x_c`; `round` when `A`'s diagonal is one
/// value with one set of derivatives (`L_d = L_q` as one parameter, the surface magnet's):
/// then `δ = −ω_e²`, and `e^{Aτ}`'s `C = cos ω_e τ`, `S = sin ω_e τ / ω_e` are the piece's
/// rotation, no sine and cosine of their own.
struct System<T> {
    a: [[T; 2]; 2],
    mu: T,
    delta: T,
    p: [[T; 2]; 2],
    xc: [T; 2],
    round: bool,
}

#[inline(always)]
fn system<T: Scalar>(q: &Params<T>, w: f64, emf: f64) -> System<T> {
    let a11 = -q.r / q.l_d;
    let a22 = -q.r / q.l_q;
    let a12 = q.l_q / q.l_d * w;
    let a21 = -(q.l_d / q.l_q * w);
    let mu = (a11 + a22) * 0.5;
    let half_diff = (a11 - a22) * 0.5;
    // δ = μ² − det A without the cancellation of μ² against a₁₁a₂₂.
    let delta = half_diff * half_diff + a12 * a21;
    let zero = T::cst(0.0);
    let jw = T::cst(w);
    let m11 = Cx { re: a11, im: -jw };
    let m22 = Cx { re: a22, im: -jw };
    let m12 = Cx { re: a12, im: zero };
    let m21 = Cx { re: a21, im: zero };
    let det = m11.mul(m22).sub(m12.mul(m21));
    let b1 = Cx { re: -(T::cst(1.0) / q.l_d), im: zero };
    let b2 = Cx { re: zero, im: -(T::cst(1.0) / q.l_q) };
    let z1 = b1.mul(m22).sub(m12.mul(b2)).div(det);
    let z2 = m11.mul(b2).sub(m21.mul(b1)).div(det);
    let det_a = a11 * a22 - a12 * a21;
    let c2 = -(q.k_e * emf / q.l_q);
    let xc = [c2 * a12 / det_a, -(c2 * a11 / det_a)];
    let round = half_diff.is_zero();
    System { a: [[a11, a12], [a21, a22]], mu, delta, p: [[z1.re, z1.im], [z2.re, z2.im]], xc, round }
}

/// `C(τ)` and `S(τ)` of `e^{Aτ}` for `δ` (module docs); with `rotation`
/// `((sin ω_e τ, cos ω_e τ), ω_e)` of a round system (`δ = −ω_e²`, [`System`]) taken from it.
#[inline(always)]
fn c_s<T: Scalar>(delta: T, tau: T, rotation: Option<((T, T), f64)>) -> (T, T) {
    let x = delta * tau * tau;
    if x.val().abs() < 1e-3 {
        let c = T::cst(1.0) + x * (T::cst(0.5) + x * (T::cst(1.0 / 24.0) + x * (1.0 / 720.0)));
        let s =
            tau * (T::cst(1.0) + x * (T::cst(1.0 / 6.0) + x * (T::cst(1.0 / 120.0) + x * (1.0 / 5040.0))));
        (c, s)
    } else if let Some(((sr, cr), w)) = rotation {
        // |ω_e τ| ≥ 0.03 here, so ω_e ≠ 0.
        (cr, sr * (1.0 / w))
    } else if delta.val() < 0.0 {
        let nu = (-delta).sqrt();
        let (s, c) = (nu * tau).sin_cos();
        (c, s / nu)
    } else {
        let nu = delta.sqrt();
        let (s, c) = (nu * tau).sinh_cosh();
        (c, s / nu)
    }
}

/// The smooth or hard leg-state sign of a phase current \[A\].
#[inline(always)]
fn sign<T: Scalar>(i: T, i_w: Option<T>) -> T {
    match i_w {
        Some(w) => (i / w).atan() * std::f64::consts::FRAC_2_PI,
        None => {
            let v = i.val();
            T::cst(if v > 0.0 {
                1.0
            } else if v < 0.0 {
                -1.0
            } else {
                0.0
            })
        }
    }
}

/// Most pieces of a half period: its start, and per leg the switching instant, the end of
/// a carried-over or start-of-half blanking, and the end of the switching blanking.
const EVENTS: usize = 10;

/// The dq current at the end of the period from `x` at its start \[A\].
pub(crate) fn step<T: Scalar>(q: &Params<T>, per: &Period, x: [T; 2]) -> [T; 2] {
    step_with(q, per, x, None).0
}

/// [`step`], and the smallest magnitude of a phase current at the start of a piece, where
/// the leg states take its sign \[A\]: how far the period is from a sign the smallest error
/// of the predicted current would turn.
pub(crate) fn step_nearest(q: &Params<f64>, per: &Period, x: [f64; 2]) -> ([f64; 2], f64) {
    step_with(q, per, x, None)
}

/// [`step`], and the period mean of the dq voltage the motor sees \[V\] (for a simulated
/// log's `ud, uq`).
pub(crate) fn step_mean(q: &Params<f64>, per: &Period, x: [f64; 2], h: f64) -> ([f64; 2], [f64; 2]) {
    let mut acc = [0.0; 2];
    let (x, _) = step_with(q, per, x, Some(&mut acc));
    (x, [acc[0] / h, acc[1] / h])
}

/// [`step`] in dual numbers (the pass with sensitivities), compiled for AVX-512 and AVX2
/// as well as the baseline and chosen at run time: the derivative arrays' arithmetic is the
/// same operations in wider registers (no contraction into fused multiply-adds), so the
/// numbers are the baseline's to the bit.
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
pub(crate) fn step_dual(
    q: &Params<super::dual::Dual>,
    per: &Period,
    x: [super::dual::Dual; 2],
) -> [super::dual::Dual; 2] {
    step_with(q, per, x, None).0
}

/// The step, and the smallest phase current magnitude at a piece's start \[A\].
#[inline(always)]
fn step_with<T: Scalar>(
    q: &Params<T>,
    per: &Period,
    x0: [T; 2],
    mut acc: Option<&mut [T; 2]>,
) -> ([T; 2], f64) {
    let sys = system(q, per.w_e, per.emf);
    let mut x = x0;
    let mut nearest = f64::INFINITY;
    for half in &per.halves[..usize::from(per.n)] {
        x = half_step(q, &sys, per, half, x, acc.as_deref_mut(), &mut nearest);
    }
    (super::acceleration::with_acceleration(q, per, x0, x), nearest)
}

#[inline(always)]
fn half_step<T: Scalar>(
    q: &Params<T>,
    sys: &System<T>,
    per: &Period,
    half: &HalfPlan,
    mut x: [T; 2],
    mut acc: Option<&mut [T; 2]>,
    nearest: &mut f64,
) -> [T; 2] {
    let zero = T::cst(0.0);
    let len = half.len;
    // Each leg's end of a turn-on blanking at the half's start: the dead time after a
    // changed command, or what the previous half's switching left.
    let t_on: [T; 3] = std::array::from_fn(|k| {
        if half.changed[k] {
            q.t_d
        } else if half.carry[k] > f64::NEG_INFINITY {
            let rest = q.t_d + half.carry[k];
            if rest.val() > 0.0 { rest } else { zero }
        } else {
            zero
        }
    });
    let sw_end: [T; 3] = std::array::from_fn(|k| q.t_d + half.t_sw[k]);
    let mut ev = [zero; EVENTS];
    let mut n = 1;
    let mut push = |t: T| {
        if t.val() < len {
            ev[n] = t;
            n += 1;
        }
    };
    for k in 0..3 {
        let t_sw = T::cst(half.t_sw[k]);
        push(t_sw);
        push(if t_on[k].val() < half.t_sw[k] { t_on[k] } else { t_sw });
        push(sw_end[k]);
    }
    let ev = &mut ev[..n];
    // Coinciding instants are one, unless their derivatives differ: at `t_d = 0` a
    // blanking's end is the instant it starts at, and the piece of length 0 between them,
    // blanked (a piece is blanked when it ends by the blanking's end), carries the
    // derivative over `t_d` from above; without it the fit could not leave that bound.
    ev.sort_unstable_by(|a, b| a.order(*b));
    let mut m = 1;
    for i in 1..ev.len() {
        if ev[i].order(ev[m - 1]).is_ne() {
            ev[m] = ev[i];
            m += 1;
        }
    }
    let ev = &ev[..m];
    let w = per.w_e;
    // (sin, cos) of the piece's electrical angle: the half's first from its own, each later
    // one rotated on from the one before.
    let mut angle: Option<(T, T)> = None;
    for (i, &t) in ev.iter().enumerate() {
        let end = ev.get(i + 1).copied().unwrap_or(T::cst(len));
        let tau = end - t;
        let tv = t.val();
        // Leg states from the plan and the blanking.
        let mut state = [0.0f64; 3];
        let mut blanked = [false; 3];
        for k in 0..3 {
            let switched = tv >= half.t_sw[k];
            let until = if switched { sw_end[k].val() } else { t_on[k].val() };
            blanked[k] = end.val() <= until;
            let on = if switched { !half.cmd[k] } else { half.cmd[k] };
            state[k] = if on && !blanked[k] { 1.0 } else { 0.0 };
        }
        let (s, c) = match angle {
            Some(sc) => sc,
            None => ((t + half.offset) * w + per.theta).sin_cos(),
        };
        let i_alpha = c * x[0] - s * x[1];
        let i_beta = s * x[0] + c * x[1];
        let r3 = 0.5 * 3f64.sqrt();
        let phase = [i_alpha, i_alpha * -0.5 + i_beta * r3, i_alpha * -0.5 - i_beta * r3];
        *nearest = phase.iter().fold(*nearest, |m, i| m.min(i.val().abs()));
        let u: [T; 3] = std::array::from_fn(|k| {
            let sg = sign(phase[k], q.i_w);
            let leg = if blanked[k] { (T::cst(1.0) - sg) * 0.5 } else { T::cst(state[k]) };
            leg * per.u_dc - q.u_th * sg
        });
        let u_alpha = (u[0] - (u[1] + u[2]) * 0.5) * (2.0 / 3.0);
        let u_beta = (u[1] - u[2]) * (1.0 / 3f64.sqrt());
        let v = [c * u_alpha + s * u_beta, c * u_beta - s * u_alpha];
        let rot = (tau * w).sin_cos();
        if let Some(acc) = acc.as_deref_mut() {
            // ∫₀^τ R(−ω s) v ds = (S v_d + C v_q, S v_q − C v_d), S = sin ωτ/ω, C = (1 − cos ωτ)/ω.
            let (sw, cw) = if (tau * w).val().abs() < 1e-6 {
                (tau, tau * tau * (0.5 * w))
            } else {
                (rot.0 * (1.0 / w), (T::cst(1.0) - rot.1) * (1.0 / w))
            };
            acc[0] = acc[0] + sw * v[0] + cw * v[1];
            acc[1] = acc[1] + sw * v[1] - cw * v[0];
        }
        x = piece(sys, x, v, rot, tau, w);
        // The next piece's angle θ + ω_e τ by the rotation at hand.
        angle = Some((s * rot.1 + c * rot.0, c * rot.1 - s * rot.0));
    }
    x
}

/// The exact step over a piece of length `tau` \[s\] with the dq voltage `v` at its start
/// and `(sin ω_e τ, cos ω_e τ)` at the electrical speed `w` \[rad/s\] (module docs).
#[inline(always)]
fn piece<T: Scalar>(sys: &System<T>, x: [T; 2], v: [T; 2], (sr, cr): (T, T), tau: T, w: f64) -> [T; 2] {
    let p = &sys.p;
    let pv = [p[0][0] * v[0] + p[0][1] * v[1], p[1][0] * v[0] + p[1][1] * v[1]];
    let y = [x[0] - pv[0] - sys.xc[0], x[1] - pv[1] - sys.xc[1]];
    let (c, s) = c_s(sys.delta, tau, sys.round.then_some(((sr, cr), w)));
    let e = (sys.mu * tau).exp();
    let a = &sys.a;
    let ay = [(a[0][0] - sys.mu) * y[0] + a[0][1] * y[1], a[1][0] * y[0] + (a[1][1] - sys.mu) * y[1]];
    let vr = [v[0] * cr + v[1] * sr, v[1] * cr - v[0] * sr];
    let pvr = [p[0][0] * vr[0] + p[0][1] * vr[1], p[1][0] * vr[0] + p[1][1] * vr[1]];
    [e * (c * y[0] + s * ay[0]) + pvr[0] + sys.xc[0], e * (c * y[1] + s * ay[1]) + pvr[1] + sys.xc[1]]
}

/// The period's state transition `Φ = ∂x(h)/∂x(0) = e^{A h}` (row-major), `h` the period's
/// length: the pieces share `A` and their voltages do not depend on the start where the leg
/// states are hard signs (Moler & Van Loan 2003, §2: the 2×2 case); plus the acceleration's
/// term ([`super::acceleration::transition_terms`]).
pub(crate) fn transition<T: Scalar>(q: &Params<T>, per: &Period) -> [T; 4] {
    let s = system(q, per.w_e, per.emf);
    let h = per.len();
    let (c, sv) = c_s(s.delta, T::cst(h), None);
    let e = (s.mu * h).exp();
    let acc = super::acceleration::transition_terms(q, per);
    [
        e * (c + sv * (s.a[0][0] - s.mu)) + acc[0],
        e * (sv * s.a[0][1]) + acc[1],
        e * (sv * s.a[1][0]) + acc[2],
        e * (c + sv * (s.a[1][1] - s.mu)) + acc[3],
    ]
}

#[cfg(test)]
pub(super) mod tests;
