//! Magnetic saturation with cross-saturation: the algebraic current-from-flux model of
//! Hinkkanen, Pescetto, Mölsä, Saarakkala, Pellegrino and Bojoi, "Sensorless
//! self-commissioning of synchronous reluctance motors at standstill without rotor
//! locking", IEEE Trans. Ind. Appl. 53(3), 2017, with the magnets as a constant MMF on the
//! d axis (the Norton form motulator uses for PM machines).
//!
//! Why this model and not a polynomial of the flux in the current: it is derived from a
//! magnetic energy, so the incremental inductance matrix is symmetric (reciprocity holds
//! by construction, the torque is consistent); it has five inverse-inductance coefficients
//! and four small integer exponents for both axes and their coupling; it gives the current
//! from the flux explicitly, which is what a simulation with flux states needs; and it has
//! published fits to measured machines to compare with.

use crate::error::{Error, Result};
use crate::model::Parameter;
use serde::{Deserialize, Serialize};

/// The integer exponents `(S, T, U, V)` of the algebraic saturation model: d-axis
/// self-saturation `|ψ_d|^S`, q-axis `|ψ_q|^T`, cross-saturation `|ψ_d|^U |ψ_q|^V`.
/// Hinkkanen et al. (2017) choose them from small integers per machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SaturationExponents {
    /// `S`, d-axis self-saturation.
    pub s: u32,
    /// `T`, q-axis self-saturation.
    pub t: u32,
    /// `U`, the d-axis exponent of cross-saturation.
    pub u: u32,
    /// `V`, the q-axis exponent of cross-saturation.
    pub v: u32,
}

impl Default for SaturationExponents {
    fn default() -> Self {
        Self { s: 4, t: 1, u: 1, v: 0 }
    }
}

/// Names of the saturation model's coefficients, in [`Saturation::theta`] order, with units.
pub const SATURATION_PARAMETERS: [(&str, &str); 6] = [
    ("a_d0", "1/H"),
    ("a_dd", "A/(V s)^(S+1)"),
    ("a_q0", "1/H"),
    ("a_qq", "A/(V s)^(T+1)"),
    ("a_dq", "A/(V s)^(U+V+3)"),
    ("psi_f", "V s"),
];

/// The algebraic saturation model: the dq current \[A, peak\] from the dq flux linkage
/// \[V s, amplitude-invariant\]:
///
/// ```text
/// i_d = G_d ψ_d − i_f,   G_d = a_d0 + a_dd |ψ_d|^S + a_dq/(V+2) |ψ_d|^U |ψ_q|^(V+2)
/// i_q = G_q ψ_q,         G_q = a_q0 + a_qq |ψ_q|^T + a_dq/(U+2) |ψ_d|^(U+2) |ψ_q|^V
/// ```
///
/// with the magnets' MMF `i_f = (a_d0 + a_dd ψ_f^S) ψ_f` fixed by the no-load flux `ψ_f`
/// (the flux at zero current), so that the model carries the same `ψ_f` as the linear
/// models. `a_d0`, `a_q0` are the unsaturated inverse inductances (`1/L_d0`, `1/L_q0`);
/// `a_dd`, `a_qq`, `a_dq` ≥ 0 the self- and cross-saturation. Source: Hinkkanen et al.,
/// IEEE Trans. Ind. Appl. 53(3) 2017, eqs. (6)–(8), the PM as in motulator's PM-SyRM
/// examples (Aalto University, MIT licence).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Saturation {
    /// `a_d0` \[1/H\].
    pub a_d0: f64,
    /// `a_dd` \[A/(V s)^(S+1)\].
    pub a_dd: f64,
    /// `a_q0` \[1/H\].
    pub a_q0: f64,
    /// `a_qq` \[A/(V s)^(T+1)\].
    pub a_qq: f64,
    /// `a_dq` \[A/(V s)^(U+V+3)\].
    pub a_dq: f64,
    /// No-load flux linkage `ψ_f` \[V s\] (d axis).
    pub psi_f: f64,
    /// The exponents `(S, T, U, V)`.
    #[serde(default)]
    pub exponents: SaturationExponents,
}

/// The derivatives of the current with respect to the flux and the coefficients at one flux.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentDerivatives {
    /// The current `[i_d, i_q]` \[A\].
    pub i: [f64; 2],
    /// `∂i/∂ψ`, the incremental inverse inductance matrix `[[Γ_dd, Γ_dq], [Γ_qd, Γ_qq]]`
    /// \[1/H\], symmetric.
    pub gamma: [[f64; 2]; 2],
    /// `∂i/∂θ` for θ in [`SATURATION_PARAMETERS`] order: `d_theta[j] = [∂i_d/∂θ_j, ∂i_q/∂θ_j]`.
    pub d_theta: [[f64; 2]; 6],
}

/// Inductances at one operating point \[H\]: see [`Saturation::inductances`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Inductances {
    /// The operating point's current `[i_d, i_q]` \[A\].
    pub i: [f64; 2],
    /// The flux linkage there `[ψ_d, ψ_q]` \[V s\].
    pub psi: [f64; 2],
    /// Apparent `L_d = (ψ_d − ψ_f)/i_d` \[H\] (`None` at `i_d = 0`).
    pub l_d_apparent: Option<f64>,
    /// Apparent `L_q = ψ_q/i_q` \[H\] (`None` at `i_q = 0`).
    pub l_q_apparent: Option<f64>,
    /// Incremental `∂ψ_d/∂i_d` \[H\].
    pub l_dd: f64,
    /// Incremental `∂ψ_q/∂i_q` \[H\].
    pub l_qq: f64,
    /// Incremental cross term `∂ψ_d/∂i_q = ∂ψ_q/∂i_d` \[H\].
    pub l_dq: f64,
}

/// The coefficients' parameter metadata in [`SATURATION_PARAMETERS`] order, scaled by
/// `nominal` (e.g. the start values): `a_d0`, `a_q0` positive, the saturation terms
/// non-negative, `ψ_f` free.
pub fn saturation_parameters(nominal: &[f64]) -> Vec<Parameter> {
    SATURATION_PARAMETERS
        .iter()
        .zip(nominal)
        .enumerate()
        .map(|(j, ((name, unit), &n))| {
            let scale = if n.abs() > 0.0 { n.abs() } else { 1.0 };
            let mut p = Parameter::free(name, unit, scale);
            if j < 5 {
                p.lower = if j == 0 || j == 2 { 1e-9 * scale } else { 0.0 };
            }
            p
        })
        .collect()
}

fn pow(x: f64, n: u32) -> f64 {
    x.abs().powi(n as i32)
}

impl Saturation {
    /// The model with coefficients `theta` in [`SATURATION_PARAMETERS`] order.
    pub fn from_theta(theta: &[f64], exponents: SaturationExponents) -> Self {
        let g = |j: usize| theta.get(j).copied().unwrap_or(0.0);
        Self { a_d0: g(0), a_dd: g(1), a_q0: g(2), a_qq: g(3), a_dq: g(4), psi_f: g(5), exponents }
    }

    /// The coefficients in [`SATURATION_PARAMETERS`] order.
    pub fn theta(&self) -> [f64; 6] {
        [self.a_d0, self.a_dd, self.a_q0, self.a_qq, self.a_dq, self.psi_f]
    }

    /// The magnetically linear machine `L_d`, `L_q` \[H\], `ψ_f` \[V s\] as this model
    /// (every saturation coefficient zero).
    pub fn linear(l_d: f64, l_q: f64, psi_f: f64) -> Self {
        Self {
            a_d0: 1.0 / l_d,
            a_dd: 0.0,
            a_q0: 1.0 / l_q,
            a_qq: 0.0,
            a_dq: 0.0,
            psi_f,
            exponents: SaturationExponents::default(),
        }
    }

    /// Checks the coefficients: `a_d0`, `a_q0` positive, the saturation terms non-negative,
    /// all finite (then `∂i/∂ψ` is positive definite everywhere and the flux of a current
    /// is unique).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the coefficient.
    pub fn check(&self) -> Result<()> {
        self.check_with(true)
    }

    /// [`Saturation::check`] without the sign of the saturation terms: slightly negative
    /// ones (a fit's finite-difference probe at their bound zero) stay usable near zero
    /// flux, and [`Saturation::flux`] reports where they are not.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the coefficient.
    pub(crate) fn check_usable(&self) -> Result<()> {
        self.check_with(false)
    }

    fn check_with(&self, signs: bool) -> Result<()> {
        let names = SATURATION_PARAMETERS;
        for (j, v) in self.theta().into_iter().enumerate() {
            let bad = !v.is_finite() || (signs && j < 5 && v < 0.0) || ((j == 0 || j == 2) && v <= 0.0);
            if bad {
                return Err(Error::InvalidParameter {
                    name: names[j].0.into(),
                    value: v,
                    reason: if signs {
                        "the saturation model needs finite a_d0, a_q0 > 0 and a_dd, a_qq, a_dq ≥ 0"
                    } else {
                        "the saturation model needs finite coefficients with a_d0, a_q0 > 0"
                    }
                    .into(),
                });
            }
        }
        Ok(())
    }

    /// The magnets' MMF `i_f = (a_d0 + a_dd |ψ_f|^S) ψ_f` \[A\].
    pub fn i_f(&self) -> f64 {
        (self.a_d0 + self.a_dd * pow(self.psi_f, self.exponents.s)) * self.psi_f
    }

    /// The current `[i_d, i_q]` \[A\] at the flux `psi = [ψ_d, ψ_q]` \[V s\].
    pub fn current(&self, psi: [f64; 2]) -> [f64; 2] {
        let e = self.exponents;
        let [d, q] = psi;
        let g_d = self.a_d0
            + self.a_dd * pow(d, e.s)
            + self.a_dq / f64::from(e.v + 2) * pow(d, e.u) * pow(q, e.v + 2);
        let g_q = self.a_q0
            + self.a_qq * pow(q, e.t)
            + self.a_dq / f64::from(e.u + 2) * pow(d, e.u + 2) * pow(q, e.v);
        [g_d * d - self.i_f(), g_q * q]
    }

    /// The current with its derivatives in the flux and the coefficients at `psi` \[V s\].
    pub fn derivatives(&self, psi: [f64; 2]) -> CurrentDerivatives {
        let e = self.exponents;
        let [d, q] = psi;
        let (sd, sq) = (d.signum(), q.signum());
        let (ad, aq) = (d.abs(), q.abs());
        let (fs, ft, fu, fv) = (f64::from(e.s), f64::from(e.t), f64::from(e.u), f64::from(e.v));
        let cross_d = pow(ad, e.u) * pow(aq, e.v + 2) / (fv + 2.0);
        let cross_q = pow(ad, e.u + 2) * pow(aq, e.v) / (fu + 2.0);
        let i = self.current(psi);
        let g_dd = self.a_d0 + (fs + 1.0) * self.a_dd * pow(ad, e.s) + (fu + 1.0) * self.a_dq * cross_d;
        let g_qq = self.a_q0 + (ft + 1.0) * self.a_qq * pow(aq, e.t) + (fv + 1.0) * self.a_dq * cross_q;
        let g_dq = self.a_dq * sd * sq * pow(ad, e.u + 1) * pow(aq, e.v + 1);
        let pf = pow(self.psi_f, e.s);
        let d_theta = [
            [d - self.psi_f, 0.0],
            [pow(ad, e.s) * d - pf * self.psi_f, 0.0],
            [0.0, q],
            [0.0, pow(aq, e.t) * q],
            [cross_d * d, cross_q * q],
            [-(self.a_d0 + (fs + 1.0) * self.a_dd * pf), 0.0],
        ];
        CurrentDerivatives { i, gamma: [[g_dd, g_dq], [g_dq, g_qq]], d_theta }
    }

    /// The flux `[ψ_d, ψ_q]` \[V s\] that carries the current `i` \[A\]: the inverse of
    /// [`Saturation::current`] by damped Newton steps (the map is the gradient of a convex
    /// co-energy, so the solution is unique), to `1e-13` of the flux scale.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for non-finite coefficients or `a_d0`, `a_q0` not
    /// positive; [`Error::InvalidOption`] (`current`) for a non-finite current or no
    /// convergence in 100 steps (also where negative saturation terms leave `∂i/∂ψ` not
    /// positive definite).
    pub fn flux(&self, i: [f64; 2]) -> Result<[f64; 2]> {
        self.check_usable()?;
        if !(i[0].is_finite() && i[1].is_finite()) {
            return Err(Error::InvalidOption {
                option: "current".into(),
                reason: format!("the current {i:?} A is not finite"),
            });
        }
        let mut psi = [self.psi_f + i[0] / self.a_d0, i[1] / self.a_q0];
        let scale = self.psi_f.abs() + (i[0].abs() + i[1].abs()) / self.a_d0.min(self.a_q0) + 1e-12;
        let residual = |p: [f64; 2]| {
            let c = self.current(p);
            [c[0] - i[0], c[1] - i[1]]
        };
        let norm = |r: [f64; 2]| r[0].hypot(r[1]);
        let mut r = residual(psi);
        for _ in 0..100 {
            let g = self.derivatives(psi).gamma;
            let det = g[0][0] * g[1][1] - g[0][1] * g[1][0];
            if !(det > 0.0 && g[0][0] > 0.0) {
                break;
            }
            let step = [(g[1][1] * r[0] - g[0][1] * r[1]) / det, (g[0][0] * r[1] - g[1][0] * r[0]) / det];
            let mut lambda = 1.0;
            let (mut next, mut r_next) = (psi, r);
            while lambda > 1e-6 {
                next = [psi[0] - lambda * step[0], psi[1] - lambda * step[1]];
                r_next = residual(next);
                if norm(r_next) < norm(r) || norm(r_next) == 0.0 {
                    break;
                }
                lambda *= 0.5;
            }
            let moved = lambda * step[0].hypot(step[1]);
            (psi, r) = (next, r_next);
            if moved <= 1e-13 * scale || norm(r) == 0.0 {
                return Ok(psi);
            }
        }
        if norm(r) <= 1e-9 * (1.0 + i[0].abs() + i[1].abs()) {
            return Ok(psi);
        }
        Err(Error::InvalidOption {
            option: "current".into(),
            reason: format!(
                "the flux of the current {i:?} A did not converge (coefficients {:?})",
                self.theta()
            ),
        })
    }

    /// The apparent and incremental inductances at the current `i` \[A\] (incremental:
    /// the inverse of `∂i/∂ψ`).
    ///
    /// # Errors
    /// Those of [`Saturation::flux`].
    pub fn inductances(&self, i: [f64; 2]) -> Result<Inductances> {
        let psi = self.flux(i)?;
        let g = self.derivatives(psi).gamma;
        let det = g[0][0] * g[1][1] - g[0][1] * g[1][0];
        let apparent = |num: f64, den: f64| (den.abs() > 1e-9).then(|| num / den);
        Ok(Inductances {
            i,
            psi,
            l_d_apparent: apparent(psi[0] - self.psi_f, i[0]),
            l_q_apparent: apparent(psi[1], i[1]),
            l_dd: g[1][1] / det,
            l_qq: g[0][0] / det,
            l_dq: -g[0][1] / det,
        })
    }

    /// Electromagnetic torque `T_e = 1.5 n_p (ψ_d i_q − ψ_q i_d)` \[N m\] at the flux `psi`
    /// \[V s\] (MODEL.md §2, amplitude-invariant dq).
    pub fn torque(&self, n_p: u32, psi: [f64; 2]) -> f64 {
        flux_torque(n_p, self.current(psi), psi)
    }
}

/// Electromagnetic torque `T_e = 1.5 n_p (ψ_d i_q − ψ_q i_d)` \[N m\] of the dq current `i`
/// \[A, peak\] and flux linkage `psi` \[V s\] (MODEL.md §2, amplitude-invariant dq).
pub(crate) fn flux_torque(n_p: u32, i: [f64; 2], psi: [f64; 2]) -> f64 {
    1.5 * f64::from(n_p) * (psi[0] * i[1] - psi[1] * i[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor() -> Saturation {
        Saturation {
            a_d0: 333.0,
            a_dd: 2.0e5,
            a_q0: 143.0,
            a_qq: 4.0e3,
            a_dq: 3.0e4,
            psi_f: 0.15,
            exponents: SaturationExponents { s: 4, t: 2, u: 1, v: 0 },
        }
    }

    #[test]
    fn derivatives_match_differences() {
        let m = motor();
        let psi = [0.12, -0.05];
        let d = m.derivatives(psi);
        let h = 1e-7;
        for k in 0..2 {
            let mut p = psi;
            p[k] += h;
            let (ip, mut pm) = (m.current(p), psi);
            pm[k] -= h;
            let im = m.current(pm);
            for r in 0..2 {
                let fd = (ip[r] - im[r]) / (2.0 * h);
                assert!(
                    (fd - d.gamma[r][k]).abs() < 1e-5 * (1.0 + fd.abs()),
                    "{r}{k}: {fd} {}",
                    d.gamma[r][k]
                );
            }
        }
        let theta = m.theta();
        for j in 0..6 {
            let step = 1e-6 * theta[j].abs();
            let mut tp = theta;
            tp[j] += step;
            let mut tm = theta;
            tm[j] -= step;
            let (ip, im) = (
                Saturation::from_theta(&tp, m.exponents).current(psi),
                Saturation::from_theta(&tm, m.exponents).current(psi),
            );
            for r in 0..2 {
                let fd = (ip[r] - im[r]) / (2.0 * step);
                assert!(
                    (fd - d.d_theta[j][r]).abs() < 1e-5 * (1.0 + fd.abs()),
                    "{j}/{r}: {fd} {:?}",
                    d.d_theta[j]
                );
            }
        }
    }

    #[test]
    fn flux_inverts_current_and_no_load_flux_is_psi_f() {
        let m = motor();
        let zero = m.flux([0.0, 0.0]).unwrap();
        assert!((zero[0] - 0.15).abs() < 1e-12 && zero[1].abs() < 1e-12);
        for i in [[3.0, 10.0], [-8.0, -5.0], [0.0, 20.0]] {
            let psi = m.flux(i).unwrap();
            let back = m.current(psi);
            assert!((back[0] - i[0]).abs() < 1e-9 && (back[1] - i[1]).abs() < 1e-9);
        }
        assert!(m.flux([f64::NAN, 0.0]).is_err());
    }
}
