//! The exact step of the salient PMSM: the exponential of an augmented autonomous linear
//! system applied to a vector (Van Loan 1978, "Computing integrals involving the matrix
//! exponential", IEEE TAC 23(3)); the method is described in [`crate::pmsm::model::ipm`].
//!
//! `e^{Mh} z` is summed as the Taylor series `Σ (Mh)^j z / j!` on the vector with
//! structured products; substeps keep `ρ ≤ 0.5`, and beyond 64 substeps the 13 × 13 matrix
//! is formed by scaling and squaring (Moler & Van Loan 2003, "Nineteen dubious ways to
//! compute the exponential of a matrix, twenty-five years later", SIAM Review 45(1)).

use crate::pmsm::model::interval::{IntervalSource, VoltageHold};
use nalgebra::Complex;
use nalgebra::SMatrix;

/// The data of the IPM step, independent of θ: its intervals' source (the experiment's
/// speed and voltage channels, shared, not copied), from which each interval's speeds and
/// start-of-period voltage follow ([`IntervalSource::speeds`],
/// [`IntervalSource::start_voltage`]), its voltage hold and the inverter's error directions.
#[derive(Clone, Debug)]
pub struct IpmInputs {
    /// Sample time, pole pairs, speed and voltage of the intervals.
    pub source: IntervalSource,
    /// The voltage hold that the start-of-period voltage refers to.
    pub hold: VoltageHold,
    /// The inverter's voltage error per unit `v_dt` at the start of the period, held like
    /// the voltage (empty without the inverter model), length N−1.
    pub dt: Vec<Complex<f64>>,
}

impl IpmInputs {
    /// Interval k's dq voltage at the start of the period \[V\] for the model's hold
    /// ([`IntervalSource::start_voltage`]).
    ///
    /// # Panics
    /// If k ≥ N − 1.
    #[inline]
    pub fn u0(&self, k: usize) -> Complex<f64> {
        self.source.start_voltage(self.hold, k)
    }
}

/// θ-dependent coefficients of the IPM step (ratios precomputed once per θ).
#[derive(Clone, Debug)]
pub struct IpmCoefficients {
    /// Number of parameters n_θ (4, or 5 with `v_dt`).
    pub(crate) nth: usize,
    /// Inverter voltage error `v_dt` \[V\] (0 without the inverter model).
    pub(crate) v_dt: f64,
    pub(crate) h: f64,
    pub(crate) k_e: f64,
    /// `1/L_d`, `1/L_q` \[1/H\].
    pub(crate) inv_l_d: f64,
    pub(crate) inv_l_q: f64,
    /// `R_s/L_d`, `R_s/L_q` \[1/s\].
    pub(crate) r_l_d: f64,
    pub(crate) r_l_q: f64,
    /// `L_q/L_d`, `L_d/L_q`.
    pub(crate) l_q_l_d: f64,
    pub(crate) l_d_l_q: f64,
    /// `max(R_s/L_d, R_s/L_q)` \[1/s\]: the decay part of the spectral scale.
    pub(crate) r_l_max: f64,
}

impl IpmCoefficients {
    /// The coefficients at `θ = (r_s, l_d, l_q, k_e)` without the inverter term, computed
    /// as [`crate::pmsm::PmsmIpm`]'s `coefficients` does but unchecked (the caller checks; `r_s`
    /// may be 0 here).
    pub(crate) fn at(h: f64, r: f64, l_d: f64, l_q: f64, k_e: f64) -> Self {
        IpmCoefficients {
            nth: 4,
            v_dt: 0.0,
            h,
            k_e,
            inv_l_d: 1.0 / l_d,
            inv_l_q: 1.0 / l_q,
            r_l_d: r / l_d,
            r_l_q: r / l_q,
            l_q_l_d: l_q / l_d,
            l_d_l_q: l_d / l_q,
            r_l_max: r / l_d.min(l_q),
        }
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

/// Augmented state without its constant 1: `x` \[A\], `s[j] = ∂x/∂θ_j`, `v` \[V\].
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Aug {
    pub(crate) x: [f64; 2],
    pub(crate) s: [[f64; 2]; 4],
    pub(crate) v: [f64; 2],
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
    /// `τ/L_d`, `τ/L_q` \[s/H\]: voltage to current slope, and `−∂f/∂R_s` per current.
    b_d: f64,
    b_q: f64,
    /// `−τ K_e √(2/3) ω_m / L_q` \[A\]: back-EMF, the column of the constant 1.
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
pub(crate) fn advance<const SENS: bool>(
    c: &IpmCoefficients,
    inp: &IpmInputs,
    k: usize,
    z: &mut Aug,
    one: f64,
) {
    let (w_e, emf) = inp.source.speeds(k);
    advance_at::<SENS>(c, inp.hold, w_e, emf, z, one);
}

/// [`advance`] for one period given by its values: the hold, the electrical speed `w_e`
/// \[rad/s\] and the back-EMF per unit `K_e`, `emf = √(2/3) ω_m` \[rad/s\].
pub(crate) fn advance_at<const SENS: bool>(
    c: &IpmCoefficients,
    hold: VoltageHold,
    w_e: f64,
    emf: f64,
    z: &mut Aug,
    one: f64,
) {
    let w_v = match hold {
        VoltageHold::Stator => w_e,
        VoltageHold::Dq => 0.0,
    };
    let rho = c.h * (c.r_l_max + w_e.abs());
    if !rho.is_finite() {
        *z = Aug { x: [f64::NAN; 2], s: [[f64::NAN; 2]; 4], v: [f64::NAN; 2] };
        return;
    }
    if rho <= RHO_MAX {
        Sub::new(c, c.h, w_e, emf, w_v).propagate::<SENS>(z, one);
        return;
    }
    let m = (rho / RHO_MAX).ceil();
    if m <= MAX_SUBSTEPS as f64 {
        let sub = Sub::new(c, c.h / m, w_e, emf, w_v);
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
    let mt = Sub::new(c, tau, w_e, emf, w_v).dense();
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::GreyBoxModel;
    use crate::pmsm::PmsmIpm;
    use crate::pmsm::SQRT_2_3;
    use crate::pmsm::model::interval::IntervalVoltage;

    fn coefficients() -> IpmCoefficients {
        let source = IntervalSource {
            h: 2e-4,
            n_p: 4.0,
            w_m: Vec::new().into(),
            u: IntervalVoltage::Start(Vec::new()),
        };
        let inp = IpmInputs { source, hold: VoltageHold::Stator, dt: vec![] };
        PmsmIpm::new(4, VoltageHold::Stator).coefficients(&[0.35, 3.2e-3, 7.5e-3, 0.4164], &inp).unwrap()
    }

    /// The vector series with substeps and the dense scaling-and-squaring path agree.
    #[test]
    fn substeps_agree_with_scaling_and_squaring() {
        let c = coefficients();
        for (w_e, w_v) in [(3000.0, 3000.0), (-4500.0, -4500.0), (3000.0, 0.0)] {
            let emf = SQRT_2_3 * w_e / 2.0;
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
