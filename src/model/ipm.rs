//! Interior-magnet (salient) PMSM, `L_d ≠ L_q`, with the exact sampled-data step.
//!
//! State and output `x = y = (i_d, i_q)` [A, peak]; parameters `θ = (r_s, l_d, l_q, k_e)`
//! [Ω, H, H, V s/rad]. Continuous model (thesis Tenerz 2011, section 2 and eq. 5.1;
//! MODEL.md §2), with `ω_e = n_p ω_m` and the back-EMF `e = √(2/3) K_e ω_m = ω_e ψ_f`:
//!
//! ```text
//! L_d di_d/dt = v_d − R_s i_d + ω_e L_q i_q
//! L_q di_q/dt = v_q − R_s i_q − ω_e L_d i_d − e
//! ```
//!
//! `ω_m` is the interval mean `(ω_m[k] + ω_m[k+1])/2`, so the system is linear and
//! time-invariant over each period `[0, h)`. The voltage over the period (MODEL.md §4) is
//! `v = u[k]` (dq hold) or, held in the stator frame, `v(s) = u₀ e^{−jω_e s}` in complex dq
//! notation with `u₀ = u[k] jφ/(1 − e^{−jφ})`, `φ = ω_e h` (`u[k]` is the period mean).
//!
//! # Method
//!
//! Unlike the SPM there is no scalar complex form, so the step is the exponential of an
//! augmented autonomous linear system (Van Loan 1978, "Computing integrals involving the
//! matrix exponential", IEEE TAC 23(3)): `z = (x, S, v, 1)`, `ż = M z`, `z(h) = e^{Mh} z(0)`,
//! where `v̇ = −jω_e v` (stator hold; `v̇ = 0` for the dq hold) generates the rotating voltage
//! and `S = ∂x/∂θ` (2 × 4) obeys the forward-sensitivity equations
//!
//! ```text
//! Ṡ_j = A S_j + ∂f/∂θ_j,   f = ẋ,   A = [[−R_s/L_d, ω_e L_q/L_d], [−ω_e L_d/L_q, −R_s/L_q]]
//! ∂f/∂R_s = (−i_d/L_d, −i_q/L_q)      ∂f/∂L_d = (−f_d/L_d, −ω_e i_d/L_q)
//! ∂f/∂L_q = (ω_e i_q/L_d, −f_q/L_q)   ∂f/∂K_e = (0, −√(2/3) ω_m/L_q)
//! ```
//!
//! which are linear in `(x, v, 1)`. `S(0)` is the sensitivity at the start of the period, so
//! `S(h) = ∂x(h)/∂x(0) · S(0) + ∂x(h)/∂θ` is the exact derivative of the exact step.
//! `e^{Mh} z` is summed as the Taylor series `Σ (Mh)^j z / j!` applied to the vector (only
//! structured matrix-vector products, no allocation), until two consecutive terms fall below
//! `10⁻¹⁷` of the sum in every block (x, each column of S, v). When the spectral scale
//! `ρ = (R_s/min(L_d, L_q) + |ω_e|) h` exceeds 0.5 the period is split into `⌈2ρ⌉` equal
//! substeps, exact because the augmented system is autonomous; beyond 64 substeps (a very
//! stiff θ or a huge speed) the 13 × 13 matrix `e^{Mh}` is formed by scaling and squaring
//! instead, so the cost grows with `log ρ`, not `ρ`.

use super::spm::{check_positive, current_outputs, intervals, k_e_param, positive_param};
use super::{GreyBoxModel, Parameter, Prepared, VoltageHold};
use crate::data::Experiment;
use crate::error::{Error, Result};
use nalgebra::{Complex, SMatrix};

/// Per-interval data of the IPM step, independent of θ (index k = 0..N−2).
#[derive(Clone, Debug)]
pub struct IpmInputs {
    /// Sample time h [s].
    pub h: f64,
    /// The voltage hold that `u0` refers to.
    pub hold: VoltageHold,
    /// Interval-mean electrical speed ω_e [rad/s], length N−1.
    pub w_e: Vec<f64>,
    /// `√(2/3)` × interval-mean mechanical speed [rad/s], length N−1: back-EMF per unit K_e.
    pub emf: Vec<f64>,
    /// dq voltage at the start of the period [V], length N−1: `u[k]` (dq hold) or
    /// `u₀ = u[k] jφ/(1 − e^{−jφ})` (stator hold).
    pub u0: Vec<Complex<f64>>,
}

/// θ-dependent coefficients of the IPM step (ratios precomputed once per θ).
#[derive(Clone, Debug)]
pub struct IpmCoefficients {
    h: f64,
    k_e: f64,
    /// `1/L_d`, `1/L_q` [1/H].
    inv_l_d: f64,
    inv_l_q: f64,
    /// `R_s/L_d`, `R_s/L_q` [1/s].
    r_l_d: f64,
    r_l_q: f64,
    /// `L_q/L_d`, `L_d/L_q`.
    l_q_l_d: f64,
    l_d_l_q: f64,
    /// `max(R_s/L_d, R_s/L_q)` [1/s]: the decay part of the spectral scale.
    r_l_max: f64,
}

/// Interior-magnet PMSM model with exact sampled-data step and exact forward sensitivities.
///
/// Parameters `(r_s [Ω], l_d [H], l_q [H], k_e [V s/rad])`; `r_s`, `l_d`, `l_q` bounded
/// positive, `k_e` unbounded (a negative estimate means the log's sign convention differs).
/// State and outputs `(i_d, i_q)` [A]. Source: thesis Tenerz 2011 sections 2 and 5;
/// MODEL.md §2, §4; the method is described in the [module docs](self).
#[derive(Clone, Debug)]
pub struct PmsmIpm {
    hold: VoltageHold,
    params: Vec<Parameter>,
}

impl PmsmIpm {
    /// IPM model with the given voltage hold and default parameter metadata.
    pub fn new(hold: VoltageHold) -> Self {
        Self {
            hold,
            params: vec![
                positive_param("r_s", "ohm"),
                positive_param("l_d", "H"),
                positive_param("l_q", "H"),
                k_e_param(),
            ],
        }
    }
    /// The voltage hold this model assumes.
    pub fn hold(&self) -> VoltageHold {
        self.hold
    }
    /// Mutable parameter metadata (bounds, fixed flags, nominal values), length 4.
    pub fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl Default for PmsmIpm {
    /// Stator-frame voltage hold (what an inverter does).
    fn default() -> Self {
        Self::new(VoltageHold::default())
    }
}

/// Relative size below which a Taylor term no longer changes a block of the sum.
const TOL: f64 = 1e-17;
/// Largest spectral scale `ρ` of one substep of the vector series.
const RHO_MAX: f64 = 0.5;
/// Most substeps of the vector series; more go to scaling and squaring.
const MAX_SUBSTEPS: usize = 64;
/// Safety cap on the vector series (ρ ≤ 0.5 converges within about 22 terms).
const MAX_TERMS: usize = 40;
/// `1/j` for the Taylor terms `j = 0..=MAX_TERMS` (entry 0 unused).
const INV: [f64; MAX_TERMS + 1] = {
    let mut t = [0.0; MAX_TERMS + 1];
    let mut j = 1;
    while j <= MAX_TERMS {
        t[j] = 1.0 / j as f64;
        j += 1;
    }
    t
};
/// Terms of the dense series on a scaled substep (`0.5^24/24! ≈ 10⁻³¹`).
const DENSE_TERMS: usize = 24;

/// Augmented state without its constant 1: `x` [A], `s[j] = ∂x/∂θ_j`, `v` [V].
#[derive(Clone, Copy, Debug, Default)]
struct Aug {
    x: [f64; 2],
    s: [[f64; 2]; 4],
    v: [f64; 2],
}

/// Dimension of the augmented state `(x, S, v, 1)`.
const NZ: usize = 13;
type Mat = SMatrix<f64, NZ, NZ>;

impl Aug {
    fn add(&mut self, t: &Aug) {
        for i in 0..2 {
            self.x[i] += t.x[i];
            self.v[i] += t.v[i];
            for j in 0..4 {
                self.s[j][i] += t.s[j][i];
            }
        }
    }

    fn scale(&mut self, a: f64) {
        for i in 0..2 {
            self.x[i] *= a;
            self.v[i] *= a;
            for j in 0..4 {
                self.s[j][i] *= a;
            }
        }
    }

    /// Whether this Taylor term is below `TOL` of `sum` in every block.
    fn negligible<const SENS: bool>(&self, sum: &Aug) -> bool {
        let small = |t: [f64; 2], s: [f64; 2]| t[0].abs() + t[1].abs() <= TOL * (s[0].abs() + s[1].abs());
        small(self.x, sum.x) && small(self.v, sum.v) && (!SENS || (0..4).all(|j| small(self.s[j], sum.s[j])))
    }

    fn to_vector(self) -> [f64; NZ] {
        let s = self.s;
        [
            self.x[0], self.x[1], s[0][0], s[0][1], s[1][0], s[1][1], s[2][0], s[2][1], s[3][0], s[3][1],
            self.v[0], self.v[1], 1.0,
        ]
    }

    fn from_vector(z: &[f64]) -> Aug {
        Aug {
            x: [z[0], z[1]],
            s: [[z[2], z[3]], [z[4], z[5]], [z[6], z[7]], [z[8], z[9]]],
            v: [z[10], z[11]],
        }
    }
}

/// `τ M` of one substep of length τ, as the coefficients of its structured product.
#[derive(Clone, Copy, Debug)]
struct Sub {
    /// `τ A`, row-major.
    a: [f64; 4],
    /// `τ/L_d`, `τ/L_q` [s/H]: voltage to current slope, and `−∂f/∂R_s` per current.
    b_d: f64,
    b_q: f64,
    /// `−τ K_e √(2/3) ω_m / L_q` [A]: back-EMF, the column of the constant 1.
    c_q: f64,
    /// `−τ √(2/3) ω_m / L_q`: `τ ∂f_q/∂K_e`.
    k_q: f64,
    /// `τ ω_e/L_d`, `τ ω_e/L_q`: `τ ∂f_d/∂L_q` per `i_q` and `−τ ∂f_q/∂L_d` per `i_d`.
    g_d: f64,
    g_q: f64,
    inv_l_d: f64,
    inv_l_q: f64,
    /// `τ ω_v`: rotation of the voltage (`ω_e` for the stator hold, 0 for the dq hold).
    w_v: f64,
}

impl Sub {
    fn new(c: &IpmCoefficients, tau: f64, w_e: f64, emf: f64, w_v: f64) -> Self {
        let tw = tau * w_e;
        Sub {
            a: [-tau * c.r_l_d, tw * c.l_q_l_d, -tw * c.l_d_l_q, -tau * c.r_l_q],
            b_d: tau * c.inv_l_d,
            b_q: tau * c.inv_l_q,
            c_q: -tau * c.k_e * emf * c.inv_l_q,
            k_q: -tau * emf * c.inv_l_q,
            g_d: tw * c.inv_l_d,
            g_q: tw * c.inv_l_q,
            inv_l_d: c.inv_l_d,
            inv_l_q: c.inv_l_q,
            w_v: tau * w_v,
        }
    }

    /// `τ M (t, one)`: the derivative of the augmented state scaled by τ; `one` is the
    /// constant component of `t` (1 for the state itself, 0 for the higher Taylor terms).
    #[inline(always)]
    fn apply<const SENS: bool>(&self, t: &Aug, one: f64) -> Aug {
        let [a11, a12, a21, a22] = self.a;
        let f_d = a11 * t.x[0] + a12 * t.x[1] + self.b_d * t.v[0];
        let f_q = a21 * t.x[0] + a22 * t.x[1] + self.b_q * t.v[1] + self.c_q * one;
        let mut s = [[0.0; 2]; 4];
        if SENS {
            let a = |c: [f64; 2]| [a11 * c[0] + a12 * c[1], a21 * c[0] + a22 * c[1]];
            let [r, ld, lq, ke] = [a(t.s[0]), a(t.s[1]), a(t.s[2]), a(t.s[3])];
            s[0] = [r[0] - self.b_d * t.x[0], r[1] - self.b_q * t.x[1]];
            s[1] = [ld[0] - f_d * self.inv_l_d, ld[1] - self.g_q * t.x[0]];
            s[2] = [lq[0] + self.g_d * t.x[1], lq[1] - f_q * self.inv_l_q];
            s[3] = [ke[0], ke[1] + self.k_q * one];
        }
        Aug { x: [f_d, f_q], s, v: [self.w_v * t.v[1], -self.w_v * t.v[0]] }
    }

    /// `z ← e^{τM} z` by the Taylor series applied to the vector; `one` is the constant
    /// component of z (1 for the step, 0 for its homogeneous part, the state derivative).
    #[inline(always)]
    fn propagate<const SENS: bool>(&self, z: &mut Aug, one: f64) {
        let mut t = self.apply::<SENS>(z, one);
        let mut sum = *z;
        sum.add(&t);
        let mut quiet = u8::from(t.negligible::<SENS>(&sum));
        for &inv_j in &INV[2..] {
            t = self.apply::<SENS>(&t, 0.0);
            t.scale(inv_j);
            sum.add(&t);
            if t.negligible::<SENS>(&sum) {
                quiet += 1;
                if quiet == 2 {
                    break;
                }
            } else {
                quiet = 0;
            }
        }
        *z = sum;
    }

    /// The dense `τ M` (13 × 13), column by column from [`Sub::apply`].
    fn dense(&self) -> Mat {
        let mut m = Mat::zeros();
        for c in 0..NZ {
            let mut e = [0.0; NZ];
            e[c] = 1.0;
            let one = if c == NZ - 1 { 1.0 } else { 0.0 };
            let col = self.apply::<true>(&Aug::from_vector(&e), one).to_vector();
            for (r, &v) in col.iter().enumerate().take(NZ - 1) {
                m[(r, c)] = v;
            }
        }
        m
    }
}

/// `z ← e^{hM} z`, choosing substeps or scaling and squaring from the spectral scale;
/// `one` is the constant component of z (see [`Sub::propagate`]).
fn advance<const SENS: bool>(c: &IpmCoefficients, inp: &IpmInputs, k: usize, z: &mut Aug, one: f64) {
    let w_e = inp.w_e[k];
    let w_v = match inp.hold {
        VoltageHold::Stator => w_e,
        VoltageHold::Dq => 0.0,
    };
    let rho = c.h * (c.r_l_max + w_e.abs());
    if !rho.is_finite() {
        *z = Aug { x: [f64::NAN; 2], s: [[f64::NAN; 2]; 4], v: [f64::NAN; 2] };
        return;
    }
    if rho <= RHO_MAX {
        Sub::new(c, c.h, w_e, inp.emf[k], w_v).propagate::<SENS>(z, one);
        return;
    }
    let m = (rho / RHO_MAX).ceil();
    if m <= MAX_SUBSTEPS as f64 {
        let sub = Sub::new(c, c.h / m, w_e, inp.emf[k], w_v);
        for _ in 0..m as usize {
            sub.propagate::<SENS>(z, one);
        }
        return;
    }
    // Scaling and squaring: τ = h/2^s with ρ/2^s ≤ 0.5; s ≤ 1025 for finite ρ.
    let squarings = (rho.log2() + 1.0).ceil().max(0.0) as usize;
    let mut tau = c.h;
    for _ in 0..squarings {
        tau *= 0.5;
    }
    let mt = Sub::new(c, tau, w_e, inp.emf[k], w_v).dense();
    let mut e = Mat::identity();
    let mut term = Mat::identity();
    for j in 1..=DENSE_TERMS {
        term = term * mt / j as f64;
        e += term;
    }
    for _ in 0..squarings {
        e = e * e;
    }
    let mut zv = z.to_vector();
    zv[NZ - 1] = one;
    let zn = e * nalgebra::SVector::<f64, NZ>::from(zv);
    *z = Aug::from_vector(zn.as_slice());
}

impl GreyBoxModel for PmsmIpm {
    type Inputs = IpmInputs;
    type Coefficients = IpmCoefficients;

    fn name(&self) -> &str {
        "pmsm_ipm"
    }
    fn n_states(&self) -> usize {
        2
    }
    fn n_outputs(&self) -> usize {
        2
    }
    fn output_names(&self) -> Vec<String> {
        vec!["i_d".into(), "i_q".into()]
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn state_unit(&self, _i: usize) -> String {
        "A".into()
    }

    fn prepare(&self, e: &Experiment) -> Result<Prepared<IpmInputs>> {
        let (y, x0) = current_outputs(e);
        let n = e.len() - 1;
        let mut inputs = IpmInputs {
            h: e.h(),
            hold: self.hold,
            w_e: Vec::with_capacity(n),
            emf: Vec::with_capacity(n),
            u0: Vec::with_capacity(n),
        };
        for iv in intervals(e, self.hold) {
            inputs.w_e.push(iv.w_e);
            inputs.emf.push(iv.emf);
            inputs.u0.push(iv.u0);
        }
        Ok(Prepared { name: e.name().into(), n: e.len(), y, x0, inputs })
    }

    /// Validates `θ = (r_s, l_d, l_q, k_e)` (length 4) and precomputes its ratios.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `r_s`, `l_d` or `l_q` when not positive and
    /// finite, `k_e` when not finite, and the smaller inductance when `R_s/L` or
    /// `L_q/L_d` overflows; [`Error::InvalidOption`] when θ does not have length 4.
    fn coefficients(&self, theta: &[f64], inputs: &IpmInputs) -> Result<IpmCoefficients> {
        let &[r, l_d, l_q, k_e] = theta else {
            return Err(Error::InvalidOption {
                option: "theta".into(),
                reason: format!("expected 4 values (r_s, l_d, l_q, k_e), got {}", theta.len()),
            });
        };
        check_positive("r_s", r)?;
        check_positive("l_d", l_d)?;
        check_positive("l_q", l_q)?;
        if !k_e.is_finite() {
            return Err(Error::InvalidParameter {
                name: "k_e".into(),
                value: k_e,
                reason: "must be finite".into(),
            });
        }
        let c = IpmCoefficients {
            h: inputs.h,
            k_e,
            inv_l_d: 1.0 / l_d,
            inv_l_q: 1.0 / l_q,
            r_l_d: r / l_d,
            r_l_q: r / l_q,
            l_q_l_d: l_q / l_d,
            l_d_l_q: l_d / l_q,
            r_l_max: r / l_d.min(l_q),
        };
        let ratios = [c.inv_l_d, c.inv_l_q, c.r_l_max, c.l_q_l_d, c.l_d_l_q];
        if ratios.iter().any(|v| !v.is_finite()) {
            let (name, value) = if l_d <= l_q { ("l_d", l_d) } else { ("l_q", l_q) };
            return Err(Error::InvalidParameter {
                name: name.into(),
                value,
                reason: "too small: its ratio to r_s or to the other inductance overflows".into(),
            });
        }
        Ok(c)
    }

    #[inline]
    fn step(&self, c: &IpmCoefficients, inp: &IpmInputs, k: usize, x: &[f64], x_next: &mut [f64]) {
        let u = inp.u0[k];
        let mut z = Aug { x: [x[0], x[1]], v: [u.re, u.im], ..Aug::default() };
        advance::<false>(c, inp, k, &mut z, 1.0);
        x_next.copy_from_slice(&z.x);
    }

    /// `Φ v`: the step is affine in the state, so its state derivative is the homogeneous
    /// propagation of v (voltage and constant terms zero).
    #[inline]
    fn step_state_derivative(
        &self,
        c: &IpmCoefficients,
        inp: &IpmInputs,
        k: usize,
        _x: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        let mut z = Aug { x: [v[0], v[1]], ..Aug::default() };
        advance::<false>(c, inp, k, &mut z, 0.0);
        out.copy_from_slice(&z.x);
    }

    #[inline]
    fn output_state_derivative(
        &self,
        _c: &IpmCoefficients,
        _inp: &IpmInputs,
        _k: usize,
        _x: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        out.copy_from_slice(&v[..2]);
    }

    fn has_sensitivities(&self) -> bool {
        true
    }

    /// One period with exact sensitivities; `s` and `s_next` are row-major 2 × 4,
    /// `s[4i + j] = ∂x_i/∂θ_j` with `θ = (r_s, l_d, l_q, k_e)`.
    #[inline]
    fn step_sensitivity(
        &self,
        c: &IpmCoefficients,
        inp: &IpmInputs,
        k: usize,
        x: &[f64],
        s: &[f64],
        x_next: &mut [f64],
        s_next: &mut [f64],
    ) {
        let u = inp.u0[k];
        let mut z = Aug {
            x: [x[0], x[1]],
            s: [[s[0], s[4]], [s[1], s[5]], [s[2], s[6]], [s[3], s[7]]],
            v: [u.re, u.im],
        };
        advance::<true>(c, inp, k, &mut z, 1.0);
        x_next.copy_from_slice(&z.x);
        for j in 0..4 {
            s_next[j] = z.s[j][0];
            s_next[4 + j] = z.s[j][1];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coefficients() -> IpmCoefficients {
        let inp = IpmInputs { h: 2e-4, hold: VoltageHold::Stator, w_e: vec![], emf: vec![], u0: vec![] };
        PmsmIpm::default().coefficients(&[0.35, 3.2e-3, 7.5e-3, 0.4164], &inp).unwrap()
    }

    /// The vector series with substeps and the dense scaling-and-squaring path agree.
    #[test]
    fn substeps_agree_with_scaling_and_squaring() {
        let c = coefficients();
        for (w_e, w_v) in [(3000.0, 3000.0), (-4500.0, -4500.0), (3000.0, 0.0)] {
            let emf = super::super::spm::SQRT_2_3 * w_e / 2.0;
            let z0 = Aug {
                x: [3.0, -7.0],
                s: [[1e-2, 2.0], [5.0, -3.0], [0.0, 1.0], [4.0, 0.5]],
                v: [20.0, 90.0],
            };
            let mut a = z0;
            let m = 8;
            let sub = Sub::new(&c, c.h / m as f64, w_e, emf, w_v);
            for _ in 0..m {
                sub.propagate::<true>(&mut a, 1.0);
            }
            let mt = Sub::new(&c, c.h / 8.0, w_e, emf, w_v).dense();
            let mut e = Mat::identity();
            let mut term = Mat::identity();
            for j in 1..=DENSE_TERMS {
                term = term * mt / j as f64;
                e += term;
            }
            for _ in 0..3 {
                e = e * e;
            }
            let b = e * nalgebra::SVector::<f64, NZ>::from(z0.to_vector());
            let a = a.to_vector();
            for i in 0..NZ {
                let scale = a[i].abs().max(1e-3);
                assert!((a[i] - b[i]).abs() <= 1e-12 * scale, "component {i}: {} vs {}", a[i], b[i]);
            }
        }
    }
}
