//! The interior-magnet (salient) PMSM model, `L_d ≠ L_q`: [`PmsmIpm`] documents it and its exact step.

use crate::pmsm::log::signals::check_pole_pairs;
use crate::pmsm::model::augmented::{Aug, advance};
pub use crate::pmsm::model::augmented::{IpmCoefficients, IpmInputs};
use crate::pmsm::model::interval::{IntervalSource, VoltageHold, check_finite, check_positive};
use crate::pmsm::model::inverter::dead_time_directions;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;
use greybox_observer::{SENS_ALL, SENS_NONE};

const KIND: MotorKind = MotorKind::Ipm;
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Parameter, Sensitivities};
use crate::pmsm::log::signals::DqView;
use nalgebra::Complex;

/// Interior-magnet (salient) PMSM, `L_d ≠ L_q`, with the exact sampled-data step.
///
/// State and output `x = y = (i_d, i_q)` \[A, peak\]; parameters `θ = (r_s, l_d, l_q, k_e)`
/// \[Ω, H, H, V s/rad\]. Continuous model (thesis Tenerz 2011, section 2 and eq. 5.1;
/// MODEL.md §2), with `ω_e = n_p ω_m` and the back-EMF `e = √(2/3) K_e ω_m = ω_e ψ_f`:
///
/// ```text
/// L_d di_d/dt = v_d − R_s i_d + ω_e L_q i_q
/// L_q di_q/dt = v_q − R_s i_q − ω_e L_d i_d − e
/// ```
///
/// `ω_m` is the interval mean `(ω_m[k] + ω_m[k+1])/2`, so the system is linear and
/// time-invariant over each period `[0, h)`. The voltage over the period (MODEL.md §4) is
/// `v = u[k]` (dq hold) or, held in the stator frame, `v(s) = u₀ e^{−jω_e s}` in complex dq
/// notation with `u₀ = u[k] jφ/(1 − e^{−jφ})`, `φ = ω_e h` (`u[k]` is the period mean).
///
/// # Method
///
/// Unlike the SPM there is no scalar complex form, so the step is the exponential of an
/// augmented autonomous linear system (Van Loan 1978, "Computing integrals involving the
/// matrix exponential", IEEE TAC 23(3)): `z = (x, S, v, 1)`, `ż = M z`, `z(h) = e^{Mh} z(0)`,
/// where `v̇ = −jω_e v` (stator hold; `v̇ = 0` for the dq hold) generates the rotating voltage
/// and `S = ∂x/∂θ` (2 × 4) obeys the forward-sensitivity equations
///
/// ```text
/// Ṡ_j = A S_j + ∂f/∂θ_j,   f = ẋ,   A = [[−R_s/L_d, ω_e L_q/L_d], [−ω_e L_d/L_q, −R_s/L_q]]
/// ∂f/∂R_s = (−i_d/L_d, −i_q/L_q)      ∂f/∂L_d = (−f_d/L_d, −ω_e i_d/L_q)
/// ∂f/∂L_q = (ω_e i_q/L_d, −f_q/L_q)   ∂f/∂K_e = (0, −√(2/3) ω_m/L_q)
/// ```
///
/// which are linear in `(x, v, 1)`. `S(0)` is the sensitivity at the start of the period, so
/// `S(h) = ∂x(h)/∂x(0) · S(0) + ∂x(h)/∂θ` is the exact derivative of the exact step.
/// `e^{Mh} z` is summed as the Taylor series `Σ (Mh)^j z / j!` applied to the vector (only
/// structured matrix-vector products, no allocation), until two consecutive terms fall below
/// `10⁻¹⁷` of the sum in every block (x, each column of S, v). When the spectral scale
/// `ρ = (R_s/min(L_d, L_q) + |ω_e|) h` exceeds 0.5 the period is split into `⌈2ρ⌉` equal
/// substeps, exact because the augmented system is autonomous; beyond 64 substeps (a very
/// stiff θ or a huge speed) the 13 × 13 matrix `e^{Mh}` is formed by scaling and squaring
/// instead, so the cost grows with `log ρ`, not `ρ`.
///
/// Interior-magnet PMSM model with exact sampled-data step and exact forward sensitivities.
///
/// Parameters `(r_s [Ω], l_d [H], l_q [H], k_e [V s/rad])`; `r_s`, `l_d`, `l_q` bounded
/// positive, `k_e` unbounded (a negative estimate means the log's sign convention differs).
/// State and outputs `(i_d, i_q)` \[A\]. Source: thesis Tenerz 2011 sections 2 and 5;
/// MODEL.md §2, §4; the method is described above.
#[derive(Clone, Debug)]
pub struct PmsmIpm {
    setup: PmsmSetup,
    params: Vec<Parameter>,
}

impl PmsmIpm {
    /// IPM model of a machine with `n_p` pole pairs (`ω_e = n_p ω_m`), the given voltage
    /// hold and default parameter metadata, driven by the terminal voltage. `n_p = 0` is
    /// reported by [`GreyBoxModel::prepare`] as [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError::InvalidPolePairs).
    pub fn new(n_p: u32, hold: VoltageHold) -> Self {
        Self::from_setup(PmsmSetup::new(n_p, hold))
    }

    crate::pmsm::model::setup::pmsm_model_setup!();
}

impl GreyBoxModel for PmsmIpm {
    type Inputs = IpmInputs;
    type Coefficients = IpmCoefficients;

    crate::pmsm::model::metadata::pmsm_model_metadata!(|_: &Self| KIND);

    fn prepare(&self, e: &Experiment) -> Result<IpmInputs> {
        check_pole_pairs(self.setup.n_p)?;
        let v = DqView::try_new(e)?;
        let hold = self.setup.hold;
        let source = IntervalSource::of_log(&v, self.setup.n_p, hold, self.setup.input)?;
        let mut inputs = IpmInputs { source, hold, dt: Vec::new() };
        if let Some(inv) = &self.setup.inverter {
            inputs.dt = dead_time_directions(&v, self.setup.n_p, inv)?;
        }
        Ok(inputs)
    }

    /// Validates `θ = (r_s, l_d, l_q, k_e)` (length 4) and precomputes its ratios.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `r_s`, `l_d` or `l_q` when not positive and
    /// finite, `k_e` when not finite, and the smaller inductance when `R_s/L` or
    /// `L_q/L_d` overflows; [`Error::InvalidOption`] when θ does not have length 4.
    fn coefficients(&self, theta: &[f64], inputs: &IpmInputs) -> Result<IpmCoefficients> {
        let nth = self.params.len();
        let (r, l_d, l_q, k_e, v_dt) = match *theta {
            [r, l_d, l_q, k_e] if nth == 4 => (r, l_d, l_q, k_e, 0.0),
            [r, l_d, l_q, k_e, v_dt] if nth == 5 => (r, l_d, l_q, k_e, v_dt),
            _ => {
                return Err(Error::InvalidOption {
                    option: "theta".into(),
                    reason: format!(
                        "expected {nth} values (r_s, l_d, l_q, k_e[, v_dt]), got {}",
                        theta.len()
                    ),
                });
            }
        };
        check_finite("v_dt", v_dt)?;
        let r = self.setup.series_resistance(r)?;
        check_positive("l_d", l_d)?;
        check_positive("l_q", l_q)?;
        check_finite("k_e", k_e)?;
        let c = IpmCoefficients { nth, v_dt, ..IpmCoefficients::at(inputs.source.h, r, l_d, l_q, k_e) };
        let ratios = [c.step.inv_l_d, c.step.inv_l_q, c.step.r_l_max, c.step.l_q_l_d, c.step.l_d_l_q];
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
        let u = voltage(c, inp, k);
        let mut z = Aug { x: [x[0], x[1]], v: [u.re, u.im], ..Aug::default() };
        advance::<SENS_NONE>(c, inp, k, &mut z, 1.0);
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
        advance::<SENS_NONE>(c, inp, k, &mut z, 0.0);
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

    fn sensitivities(&self) -> Option<&dyn Sensitivities<IpmInputs, IpmCoefficients>> {
        Some(self)
    }
}

impl Sensitivities<IpmInputs, IpmCoefficients> for PmsmIpm {
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
        let u = voltage(c, inp, k);
        let m = c.nth;
        let mut z = Aug {
            x: [x[0], x[1]],
            s: [[s[0], s[m]], [s[1], s[m + 1]], [s[2], s[m + 2]], [s[3], s[m + 3]]],
            v: [u.re, u.im],
        };
        advance::<SENS_ALL>(c, inp, k, &mut z, 1.0);
        x_next.copy_from_slice(&z.x);
        for j in 0..4 {
            s_next[j] = z.s[j][0];
            s_next[m + j] = z.s[j][1];
        }
        if m == 5 {
            // The step is linear in the held voltage: ∂x⁺/∂v_dt = Φ s_v + Γ(dt), the
            // homogeneous propagation of the previous sensitivity driven by the error
            // direction alone (no back-EMF, no constant term).
            let w = inp.dt[k];
            let mut zv = Aug { x: [s[4], s[9]], v: [w.re, w.im], ..Aug::default() };
            advance::<SENS_NONE>(c, inp, k, &mut zv, 0.0);
            s_next[4] = zv.x[0];
            s_next[9] = zv.x[1];
        }
    }

    #[inline]
    fn output_sensitivity(
        &self,
        _c: &IpmCoefficients,
        _inp: &IpmInputs,
        _k: usize,
        _x: &[f64],
        s: &[f64],
        dy: &mut [f64],
    ) {
        let n = dy.len();
        dy.copy_from_slice(&s[..n]);
    }
}

/// The held voltage of interval k with the inverter's error: `u0[k] + v_dt dt[k]`.
#[inline(always)]
fn voltage(c: &IpmCoefficients, inp: &IpmInputs, k: usize) -> Complex<f64> {
    if c.nth == 5 { inp.u0(k) + inp.dt[k] * c.v_dt } else { inp.u0(k) }
}
