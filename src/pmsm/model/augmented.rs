//! The exact step of the salient PMSM: the exponential of an augmented autonomous linear
//! system applied to a vector (Van Loan 1978, "Computing integrals involving the matrix
//! exponential", IEEE TAC 23(3)); the method is described in [`crate::pmsm::model::ipm`].
//!
//! `e^{Mh} z` is summed as the Taylor series `Σ (Mh)^j z / j!` on the vector with
//! structured products, in substeps that keep `ρ ≤ 0.5`: the observer crate's series
//! ([`greybox_observer::advance_substeps`], which its salient observers step with too);
//! beyond 64 substeps the 13 × 13 matrix is formed by scaling and squaring here (Moler &
//! Van Loan 2003, "Nineteen dubious ways to compute the exponential of a matrix,
//! twenty-five years later", SIAM Review 45(1)).

use crate::pmsm::model::interval::{IntervalSource, VoltageHold};
use greybox_observer::{Coefficients, SENS_ALL, Substep, advance_substeps};
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
    /// The step's ratios (`h`, `K_e`, `1/L`, `R_s/L`, `L_q/L_d`, …).
    pub(crate) step: Coefficients<f64>,
}

impl IpmCoefficients {
    /// The coefficients at `θ = (r_s, l_d, l_q, k_e)` without the inverter term, computed
    /// as [`crate::pmsm::PmsmIpm`]'s `coefficients` does but unchecked (the caller checks; `r_s`
    /// may be 0 here).
    pub(crate) fn at(h: f64, r: f64, l_d: f64, l_q: f64, k_e: f64) -> Self {
        IpmCoefficients { nth: 4, v_dt: 0.0, step: Coefficients::at(h, r, l_d, l_q, k_e) }
    }
}

/// Terms of the dense series on a scaled substep (`0.5^24/24! ≈ 10⁻³¹`).
const DENSE_TERMS: usize = 24;

/// Augmented state without its constant 1: `x` \[A\], `s[j] = ∂x/∂θ_j`, `v` \[V\].
pub(crate) type Aug = greybox_observer::Aug<f64>;

/// Dimension of the augmented state `(x, S, v, 1)`.
const NZ: usize = 13;
type Mat = SMatrix<f64, NZ, NZ>;

/// `z` as the augmented vector `(x, S, v, 1)`.
fn to_vector(z: Aug) -> [f64; NZ] {
    let s = z.s;
    [
        z.x[0], z.x[1], s[0][0], s[0][1], s[1][0], s[1][1], s[2][0], s[2][1], s[3][0], s[3][1], z.v[0],
        z.v[1], 1.0,
    ]
}

/// The augmented state of the vector `z` (its constant dropped).
fn from_vector(z: &[f64]) -> Aug {
    Aug { x: [z[0], z[1]], s: [[z[2], z[3]], [z[4], z[5]], [z[6], z[7]], [z[8], z[9]]], v: [z[10], z[11]] }
}

/// The dense `τ M` (13 × 13) of a substep, column by column from [`Substep::apply`].
fn dense(sub: &Substep<f64>) -> Mat {
    let mut m = Mat::zeros();
    for c in 0..NZ {
        let mut e = [0.0; NZ];
        e[c] = 1.0;
        let one = if c == NZ - 1 { 1.0 } else { 0.0 };
        let col = to_vector(sub.apply::<SENS_ALL>(&from_vector(&e), one));
        for (r, &v) in col.iter().enumerate().take(NZ - 1) {
            m[(r, c)] = v;
        }
    }
    m
}

/// `z ← e^{hM} z`, choosing substeps or scaling and squaring from the spectral scale;
/// `one` is the constant component of z (see [`Substep::propagate`]).
pub(crate) fn advance<const SENS: u8>(c: &IpmCoefficients, inp: &IpmInputs, k: usize, z: &mut Aug, one: f64) {
    let (w_e, emf) = inp.source.speeds(k);
    advance_at::<SENS>(c, inp.hold, w_e, emf, z, one);
}

/// [`advance`] for one period given by its values: the hold, the electrical speed `w_e`
/// \[rad/s\] and the back-EMF per unit `K_e`, `emf = √(2/3) ω_m` \[rad/s\].
pub(crate) fn advance_at<const SENS: u8>(
    c: &IpmCoefficients,
    hold: VoltageHold,
    w_e: f64,
    emf: f64,
    z: &mut Aug,
    one: f64,
) {
    if advance_substeps::<f64, SENS>(&c.step, hold.into(), w_e, emf, z, one) {
        return;
    }
    let rho = c.step.rho(w_e);
    if !rho.is_finite() {
        *z = Aug { x: [f64::NAN; 2], s: [[f64::NAN; 2]; 4], v: [f64::NAN; 2] };
        return;
    }
    let w_v = match hold {
        VoltageHold::Stator => w_e,
        VoltageHold::Dq => 0.0,
    };
    // Scaling and squaring: τ = h/2^s with ρ/2^s ≤ 0.5; s ≤ 1025 for finite ρ.
    let squarings = (rho.log2() + 1.0).ceil().max(0.0) as usize;
    let mut tau = c.step.h;
    for _ in 0..squarings {
        tau *= 0.5;
    }
    let mt = dense(&Substep::new(&c.step, tau, w_e, emf, w_v));
    let mut e = Mat::identity();
    let mut term = Mat::identity();
    for j in 1..=DENSE_TERMS {
        term = term * mt / j as f64;
        e += term;
    }
    for _ in 0..squarings {
        e = e * e;
    }
    let mut zv = to_vector(*z);
    zv[NZ - 1] = one;
    let zn = e * nalgebra::SVector::<f64, NZ>::from(zv);
    *z = from_vector(zn.as_slice());
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
            let sub = Substep::new(&c.step, c.step.h / m as f64, w_e, emf, w_v);
            for _ in 0..m {
                sub.propagate::<SENS_ALL>(&mut a, 1.0);
            }
            let mt = dense(&Substep::new(&c.step, c.step.h / 8.0, w_e, emf, w_v));
            let mut e = Mat::identity();
            let mut term = Mat::identity();
            for j in 1..=DENSE_TERMS {
                term = term * mt / j as f64;
                e += term;
            }
            for _ in 0..3 {
                e = e * e;
            }
            let b = e * nalgebra::SVector::<f64, NZ>::from(to_vector(z0));
            let a = to_vector(a);
            for i in 0..NZ {
                let scale = a[i].abs().max(1e-3);
                assert!((a[i] - b[i]).abs() <= 1e-12 * scale, "component {i}: {} vs {}", a[i], b[i]);
            }
        }
    }
}
