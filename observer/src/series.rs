//! The augmented exponential's series of the salient step: `e^{Mh} z` for the augmented
//! state `z = (i, S, v, 1)` of the dq currents, their sensitivities to `(R_s, L_d, L_q,
//! K_e)` and the voltage, summed as the Taylor series `Σ (Mh)^j z / j!` on the vector with
//! structured products, in substeps that keep the spectral scale `ρ ≤ 0.5` (Van Loan 1978,
//! "Computing integrals involving the matrix exponential", IEEE TAC 23(3)). [`crate::Ipm`]
//! steps with it, and `greybox`'s offline interior-magnet model too.

use crate::real::Real;
use crate::types::Hold;

/// Relative size below which a Taylor term no longer changes a block of the sum (`f64`;
/// `f32` stops at a hundredth of its epsilon).
const TOL: f64 = 1e-17;
/// Largest spectral scale `ρ` of one substep of the vector series.
pub const RHO_MAX: f64 = 0.5;
/// Most substeps of one step (`ρ ≤ 32`: at `h = 100 µs` an electrical speed of 3.2·10⁵
/// rad/s); beyond, [`crate::Ipm`] fails with [`crate::StepError::TooLong`] (`greybox`'s offline model
/// forms the matrix by scaling and squaring there).
pub const MAX_SUBSTEPS: usize = 64;
/// Safety cap on the vector series (`ρ ≤ 0.5` converges within about 22 terms in `f64`).
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

/// Sensitivities carried by a propagation: none (the current and the voltage only; the
/// sensitivity columns stay as they are).
pub const SENS_NONE: u8 = 0;
/// Sensitivities carried: `∂x/∂R_s` and `∂x/∂K_e` (what the observers need); the columns
/// of `L_d` and `L_q` stay as they are.
pub const SENS_R_K: u8 = 1;
/// Sensitivities carried: all four columns (`R_s`, `L_d`, `L_q`, `K_e`; the offline fit).
pub const SENS_ALL: u8 = 2;

/// The augmented state without its constant: the current `x` \[A\], its sensitivities `s`
/// to `(R_s, L_d, L_q, K_e)` (each a dq pair) and the voltage `v` \[V\].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Aug<T> {
    /// dq current \[A\].
    pub x: [T; 2],
    /// `∂x/∂R_s`, `∂x/∂L_d`, `∂x/∂L_q`, `∂x/∂K_e`.
    pub s: [[T; 2]; 4],
    /// dq voltage \[V\] (turning with the stator hold).
    pub v: [T; 2],
}

impl<T: Real> Aug<T> {
    /// Whether sensitivity column `j` (0 `R_s`, 1 `L_d`, 2 `L_q`, 3 `K_e`) is carried under
    /// the sensitivities `S` ([`SENS_NONE`], [`SENS_R_K`], [`SENS_ALL`]).
    #[inline(always)]
    const fn carried<const S: u8>(j: usize) -> bool {
        match S {
            SENS_NONE => false,
            SENS_R_K => j == 0 || j == 3,
            _ => true,
        }
    }

    #[inline(always)]
    fn add<const S: u8>(&mut self, t: &Self) {
        for i in 0..2 {
            self.x[i] = self.x[i] + t.x[i];
            self.v[i] = self.v[i] + t.v[i];
            for j in 0..4 {
                if Self::carried::<S>(j) {
                    self.s[j][i] = self.s[j][i] + t.s[j][i];
                }
            }
        }
    }

    #[inline(always)]
    fn scale<const S: u8>(&mut self, a: T) {
        for i in 0..2 {
            self.x[i] = self.x[i] * a;
            self.v[i] = self.v[i] * a;
            for j in 0..4 {
                if Self::carried::<S>(j) {
                    self.s[j][i] = self.s[j][i] * a;
                }
            }
        }
    }

    /// Whether this Taylor term is below `tol` of `sum` in every carried block.
    #[inline(always)]
    fn negligible<const S: u8>(&self, sum: &Self, tol: T) -> bool {
        let small = |t: [T; 2], s: [T; 2]| t[0].abs() + t[1].abs() <= tol * (s[0].abs() + s[1].abs());
        small(self.x, sum.x)
            && small(self.v, sum.v)
            && (0..4).all(|j| !Self::carried::<S>(j) || small(self.s[j], sum.s[j]))
    }
}

/// The parameters' ratios of the step (computed once per parameter vector).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients<T> {
    /// Sample time `h` \[s\].
    pub h: T,
    /// `K_e` \[V s/rad\].
    pub k_e: T,
    /// `1/L_d`, `1/L_q` \[1/H\].
    pub inv_l_d: T,
    /// See `inv_l_d`.
    pub inv_l_q: T,
    /// `R_s/L_d`, `R_s/L_q` \[1/s\].
    pub r_l_d: T,
    /// See `r_l_d`.
    pub r_l_q: T,
    /// `L_q/L_d`.
    pub l_q_l_d: T,
    /// `L_d/L_q`.
    pub l_d_l_q: T,
    /// `max(R_s/L_d, R_s/L_q)` \[1/s\]: the decay part of the spectral scale.
    pub r_l_max: T,
}

impl<T: Real> Coefficients<T> {
    /// The coefficients at sample time `h` \[s\], `R_s = r` \[Ω\], `L_d`, `L_q` \[H\] and
    /// `K_e` \[V s/rad\], unchecked (the caller checks).
    #[inline]
    pub fn at(h: T, r: T, l_d: T, l_q: T, k_e: T) -> Self {
        Self {
            h,
            k_e,
            inv_l_d: T::one() / l_d,
            inv_l_q: T::one() / l_q,
            r_l_d: r / l_d,
            r_l_q: r / l_q,
            l_q_l_d: l_q / l_d,
            l_d_l_q: l_d / l_q,
            r_l_max: r / l_d.min(l_q),
        }
    }

    /// The spectral scale `ρ = h (R_s/min(L) + |ω_e|)` of a whole period at `w_e` \[rad/s\].
    #[inline]
    pub fn rho(&self, w_e: T) -> T {
        self.h * (self.r_l_max + w_e.abs())
    }
}

/// `τ M` of one substep of length τ, as the coefficients of its structured product.
#[derive(Clone, Copy, Debug)]
pub struct Substep<T> {
    /// `τ A`, row-major.
    a: [T; 4],
    /// `τ/L_d`, `τ/L_q` \[s/H\]: voltage to current slope, and `−∂f/∂R_s` per current.
    b_d: T,
    b_q: T,
    /// `−τ K_e √(2/3) ω_m / L_q` \[A\]: back-EMF, the column of the constant 1.
    c_q: T,
    /// `−τ √(2/3) ω_m / L_q`: `τ ∂f_q/∂K_e`.
    k_q: T,
    /// `τ ω_e/L_d`, `τ ω_e/L_q`: `τ ∂f_d/∂L_q` per `i_q` and `−τ ∂f_q/∂L_d` per `i_d`.
    g_d: T,
    g_q: T,
    inv_l_d: T,
    inv_l_q: T,
    /// `τ ω_v`: rotation of the voltage (`ω_e` for the stator hold, 0 for the dq hold).
    w_v: T,
}

impl<T: Real> Substep<T> {
    /// A substep of length `tau` \[s\] at the electrical speed `w_e` \[rad/s\], the back-EMF
    /// per unit `K_e` `emf = √(2/3) ω_m` \[rad/s\] and the voltage's rotation `w_v`
    /// \[rad/s\] (`ω_e` held in the stator frame, 0 in dq).
    #[inline(always)]
    pub fn new(c: &Coefficients<T>, tau: T, w_e: T, emf: T, w_v: T) -> Self {
        let tw = tau * w_e;
        Self {
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
    pub fn apply<const S: u8>(&self, t: &Aug<T>, one: T) -> Aug<T> {
        let [a11, a12, a21, a22] = self.a;
        let f_d = a11 * t.x[0] + a12 * t.x[1] + self.b_d * t.v[0];
        let f_q = a21 * t.x[0] + a22 * t.x[1] + self.b_q * t.v[1] + self.c_q * one;
        let zero = T::zero();
        let mut s = [[zero; 2]; 4];
        let a = |c: [T; 2]| [a11 * c[0] + a12 * c[1], a21 * c[0] + a22 * c[1]];
        if S != SENS_NONE {
            let [r, ke] = [a(t.s[0]), a(t.s[3])];
            s[0] = [r[0] - self.b_d * t.x[0], r[1] - self.b_q * t.x[1]];
            s[3] = [ke[0], ke[1] + self.k_q * one];
        }
        if S == SENS_ALL {
            let [ld, lq] = [a(t.s[1]), a(t.s[2])];
            s[1] = [ld[0] - f_d * self.inv_l_d, ld[1] - self.g_q * t.x[0]];
            s[2] = [lq[0] + self.g_d * t.x[1], lq[1] - f_q * self.inv_l_q];
        }
        Aug { x: [f_d, f_q], s, v: [self.w_v * t.v[1], -self.w_v * t.v[0]] }
    }

    /// `z ← e^{τM} z` by the Taylor series applied to the vector; `one` is the constant
    /// component of z (1 for the step, 0 for its homogeneous part, the state derivative).
    #[inline(always)]
    pub fn propagate<const S: u8>(&self, z: &mut Aug<T>, one: T) {
        self.series::<S, false>(z, one);
    }

    /// [`Substep::propagate`] and, with `PHI`, the substep's transition `e^{τA}` (row-major
    /// 2 × 2: the current's own dynamics without voltage, back-EMF or sensitivities, the
    /// Taylor series of the matrix) in the same loop: two independent chains of products
    /// the processor overlaps, each with its own stopping rule (two terms in a row below the
    /// tolerance in every block or column), so each is the number it is alone to the bit.
    /// Without `PHI` the matrix returned is `I + τA`.
    #[inline(always)]
    fn series<const S: u8, const PHI: bool>(&self, z: &mut Aug<T>, one: T) -> [T; 4] {
        let tol = T::c(TOL).max(T::epsilon() * T::c(0.01));
        let mut t = self.apply::<S>(z, one);
        let mut sum = *z;
        sum.add::<S>(&t);
        let mut quiet = u8::from(t.negligible::<S>(&sum, tol));
        let [a11, a12, a21, a22] = self.a;
        let (mut p, mut p_sum) = ([a11, a12, a21, a22], [T::one() + a11, a12, a21, T::one() + a22]);
        let small = |x: T, y: T, u: T, v: T| x.abs() + y.abs() <= tol * (u.abs() + v.abs());
        let negligible =
            |p: &[T; 4], s: &[T; 4]| small(p[0], p[2], s[0], s[2]) && small(p[1], p[3], s[1], s[3]);
        let mut p_quiet = if PHI { u8::from(negligible(&p, &p_sum)) } else { 2 };
        for &inv_j in &INV[2..] {
            if quiet < 2 {
                t = self.apply::<S>(&t, T::zero());
                t.scale::<S>(T::c(inv_j));
                sum.add::<S>(&t);
                quiet = if t.negligible::<S>(&sum, tol) { quiet + 1 } else { 0 };
            }
            if p_quiet < 2 {
                // Column by column, the term t ← τA t / j from each unit current.
                let inv = T::c(inv_j);
                p = [
                    (a11 * p[0] + a12 * p[2]) * inv,
                    (a11 * p[1] + a12 * p[3]) * inv,
                    (a21 * p[0] + a22 * p[2]) * inv,
                    (a21 * p[1] + a22 * p[3]) * inv,
                ];
                for (s, p) in p_sum.iter_mut().zip(&p) {
                    *s = *s + *p;
                }
                p_quiet = if negligible(&p, &p_sum) { p_quiet + 1 } else { 0 };
            }
            if quiet == 2 && p_quiet == 2 {
                break;
            }
        }
        *z = sum;
        p_sum
    }
}

/// `z ← e^{hM} z` over one period of `c.h` at `w_e` \[rad/s\] and `emf = √(2/3) ω_m`, the
/// voltage held as `hold`, in the fewest substeps that keep `ρ ≤` [`RHO_MAX`]; `one` is the
/// constant component of z (see [`Substep::propagate`]). Returns `false`, `z` unchanged,
/// where `ρ` is not finite or more than [`MAX_SUBSTEPS`] substeps would be needed.
#[inline(always)]
pub fn advance_substeps<T: Real, const S: u8>(
    c: &Coefficients<T>,
    hold: Hold,
    w_e: T,
    emf: T,
    z: &mut Aug<T>,
    one: T,
) -> bool {
    advance::<T, S, false>(c, hold, w_e, emf, z, one).is_some()
}

/// [`advance_substeps`] and the period's transition `Φ = e^{hA}` (row-major 2 × 2), the
/// step's homogeneous part (no voltage, no back-EMF): the first substep's series carries
/// it beside the vector's, more substeps multiply it. `None`, `z` unchanged, where
/// [`advance_substeps`] returns `false`.
#[inline(always)]
pub fn advance_substeps_transition<T: Real, const S: u8>(
    c: &Coefficients<T>,
    hold: Hold,
    w_e: T,
    emf: T,
    z: &mut Aug<T>,
    one: T,
) -> Option<[T; 4]> {
    advance::<T, S, true>(c, hold, w_e, emf, z, one)
}

#[inline(always)]
fn advance<T: Real, const S: u8, const PHI: bool>(
    c: &Coefficients<T>,
    hold: Hold,
    w_e: T,
    emf: T,
    z: &mut Aug<T>,
    one: T,
) -> Option<[T; 4]> {
    let w_v = match hold {
        Hold::Stator => w_e,
        Hold::Dq => T::zero(),
    };
    let rho = c.rho(w_e);
    if !rho.is_finite() {
        return None;
    }
    let m = if rho <= T::c(RHO_MAX) { T::one() } else { (rho / T::c(RHO_MAX)).ceil() };
    if m > T::c(MAX_SUBSTEPS as f64) {
        return None;
    }
    // One substep is the whole period (`h / 1` is `h` to the bit).
    let sub = Substep::new(c, c.h / m, w_e, emf, w_v);
    let first = sub.series::<S, PHI>(z, one);
    let mut phi = first;
    for _ in 1..m.to_usize().unwrap_or(1) {
        sub.propagate::<S>(z, one);
        if PHI {
            let p = phi;
            phi = [
                first[0] * p[0] + first[1] * p[2],
                first[0] * p[1] + first[1] * p[3],
                first[2] * p[0] + first[3] * p[2],
                first[2] * p[1] + first[3] * p[3],
            ];
        }
    }
    Some(phi)
}
