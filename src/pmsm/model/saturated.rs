//! The saturated interior-magnet PMSM: flux linkage integrated over each period with the
//! current from the algebraic saturation model ([`Saturation`]); the one step the drive
//! simulator's saturated plant and the fitted model share ([`saturated_step`]).

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{DerivedEstimate, GreyBoxModel, Parameter, Signal};
use crate::pmsm::log::signals::{DqView, check_pole_pairs};
use crate::pmsm::model::interval::{C64, IntervalSource, SQRT_2_3, VoltageHold, VoltageInput};
use crate::pmsm::model::saturation::{Saturation, SaturationExponents, saturation_parameters};

/// The largest `(R_s Γ + |ω_e|) h` of one RK4 substep: the local error per substep is about
/// `ρ⁵/120 ≈ 8·10⁻¹¹` of the flux.
pub const SATURATED_SUBSTEP_RHO: f64 = 0.025;

/// The dq current \[A\] at the end of one period of length `h` \[s\] of the saturated
/// machine, from the current `i` \[A\] at its start: the flux `ψ = Saturation⁻¹(i)` is
/// integrated by `substeps` classical Runge–Kutta steps of
///
/// ```text
/// dψ_d/dt = u_d(s) − R_s i_d(ψ) + ω_e ψ_q
/// dψ_q/dt = u_q(s) − R_s i_q(ψ) − ω_e ψ_d
/// ```
///
/// with the voltage held in the stator frame, `u(s) = u0 e^{−jω_e s}` (complex dq; `u0` the
/// start-of-period voltage, MODEL.md §4) and `ω_e` the period's mean electrical speed
/// \[rad/s\]; then `i = Saturation(ψ)`. Source: the flux-linkage form of the PMSM (thesis
/// Tenerz 2011, ch. 2; Hinkkanen et al., IEEE Trans. Ind. Appl. 53(3) 2017), RK4 (Hairer,
/// Nørsett & Wanner, *Solving ODEs I*, II.1).
///
/// # Errors
/// Those of [`Saturation::flux`] (invalid coefficients, no convergence).
pub fn saturated_step(
    m: &Saturation,
    r_s: f64,
    i: [f64; 2],
    u0: C64,
    w_e: f64,
    h: f64,
    substeps: usize,
) -> Result<[f64; 2]> {
    let mut psi = m.flux(i)?;
    let n = substeps.max(1);
    let dt = h / n as f64;
    let f = |s: f64, p: [f64; 2]| {
        let c = m.current(p);
        let u = u0 * C64::from_polar(1.0, -w_e * s);
        [u.re - r_s * c[0] + w_e * p[1], u.im - r_s * c[1] - w_e * p[0]]
    };
    for j in 0..n {
        let s = j as f64 * dt;
        let k1 = f(s, psi);
        let k2 = f(s + 0.5 * dt, [psi[0] + 0.5 * dt * k1[0], psi[1] + 0.5 * dt * k1[1]]);
        let k3 = f(s + 0.5 * dt, [psi[0] + 0.5 * dt * k2[0], psi[1] + 0.5 * dt * k2[1]]);
        let k4 = f(s + dt, [psi[0] + dt * k3[0], psi[1] + dt * k3[1]]);
        for a in 0..2 {
            psi[a] += dt / 6.0 * (k1[a] + 2.0 * k2[a] + 2.0 * k3[a] + k4[a]);
        }
    }
    Ok(m.current(psi))
}

/// The RK4 substeps [`saturated_step`] needs for `(R_s Γ + |ω_e|) h ≤`
/// [`SATURATED_SUBSTEP_RHO`] per substep, with Γ the largest incremental inverse inductance
/// at the currents `(0, 0)`, `(±i_max, 0)`, `(0, ±i_max)` \[A\] and `w_e_max` the largest
/// electrical speed \[rad/s\].
///
/// # Errors
/// Those of [`Saturation::flux`].
pub fn saturated_substeps(m: &Saturation, r_s: f64, i_max: f64, w_e_max: f64, h: f64) -> Result<usize> {
    let mut gamma: f64 = 0.0;
    for i in [[0.0, 0.0], [i_max, 0.0], [-i_max, 0.0], [0.0, i_max], [0.0, -i_max]] {
        let g = m.derivatives(m.flux(i)?).gamma;
        gamma = gamma.max(g[0][0].abs() + g[0][1].abs()).max(g[1][1].abs() + g[1][0].abs());
    }
    let rho = (r_s.abs() * gamma + w_e_max.abs()) * h;
    Ok(((rho / SATURATED_SUBSTEP_RHO).ceil() as usize).clamp(1, 4096))
}

/// Saturated interior-magnet PMSM with cross-saturation.
///
/// State and output `x = y = (i_d, i_q)` \[A, peak\] (the flux is recovered from the current
/// at each step, so the first measurement is the initial state whatever θ); parameters
/// `θ = (r_s, a_d0, a_dd, a_q0, a_qq, a_dq, psi_f)` \[Ω, then [`SATURATION_PARAMETERS`](crate::pmsm::SATURATION_PARAMETERS)\]
/// with fixed exponents `(S, T, U, V)`. One step is [`saturated_step`] with the terminal
/// voltage held in the stator frame and a fixed number of RK4 substeps (set once per fit,
/// so that the step is a smooth function of θ); sensitivities by central finite
/// differences. Source: Hinkkanen et al., IEEE Trans. Ind. Appl. 53(3) 2017 (magnetics);
/// thesis Tenerz 2011 ch. 2 and 5 (the voltage equations, the fit).
#[derive(Clone, Debug)]
pub struct PmsmSaturated {
    n_p: u32,
    exponents: SaturationExponents,
    substeps: usize,
    params: Vec<Parameter>,
}

/// The saturated model's coefficients: the magnetics and `R_s`.
#[derive(Clone, Debug)]
pub struct SaturatedCoefficients {
    magnetics: Saturation,
    r_s: f64,
    h: f64,
}

impl PmsmSaturated {
    /// The model of a machine with `n_p` pole pairs, the exponents, `substeps` RK4 steps
    /// per period (see [`saturated_substeps`]) and parameter scales `nominal` (θ order).
    pub fn new(n_p: u32, exponents: SaturationExponents, substeps: usize, nominal: &[f64; 7]) -> Self {
        let mut params = vec![Parameter::positive("r_s", "ohm", nominal[0])];
        params.extend(saturation_parameters(&nominal[1..]));
        Self { n_p, exponents, substeps: substeps.max(1), params }
    }

    /// The exponents `(S, T, U, V)`.
    pub fn exponents(&self) -> SaturationExponents {
        self.exponents
    }

    /// The magnetics of a parameter vector θ (model order).
    pub fn magnetics(&self, theta: &[f64]) -> Saturation {
        Saturation::from_theta(&theta[1.min(theta.len())..], self.exponents)
    }
}

impl GreyBoxModel for PmsmSaturated {
    type Inputs = IntervalSource;
    type Coefficients = SaturatedCoefficients;

    fn name(&self) -> &str {
        "pmsm_ipm_saturated"
    }

    fn n_states(&self) -> usize {
        2
    }

    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new("id", "A"), Signal::new("iq", "A")]
    }

    fn input_channels(&self) -> Vec<String> {
        vec!["ud".into(), "uq".into(), "w_m".into()]
    }

    fn parameters(&self) -> &[Parameter] {
        &self.params
    }

    fn derived(&self, theta: &[f64], covariance: &[Vec<f64>]) -> Vec<DerivedEstimate> {
        let var = |j: usize| covariance.get(j).and_then(|r| r.get(j)).copied().unwrap_or(f64::NAN).max(0.0);
        let np = f64::from(self.n_p);
        let mut out = vec![DerivedEstimate {
            name: "k_e".into(),
            unit: "V s/rad".into(),
            value: np * theta[6] / SQRT_2_3,
            std_error: np * var(6).sqrt() / SQRT_2_3,
            ci95: None,
            experiment: None,
        }];
        for (name, j) in [("l_d0", 1), ("l_q0", 3)] {
            out.push(DerivedEstimate {
                name: name.into(),
                unit: "H".into(),
                value: 1.0 / theta[j],
                std_error: var(j).sqrt() / (theta[j] * theta[j]),
                ci95: None,
                experiment: None,
            });
        }
        out
    }

    fn prepare(&self, e: &Experiment) -> Result<IntervalSource> {
        check_pole_pairs(self.n_p)?;
        let v = DqView::try_new(e)?;
        IntervalSource::of_log(&v, self.n_p, VoltageHold::Stator, VoltageInput::Terminal)
    }

    fn coefficients(&self, theta: &[f64], inputs: &IntervalSource) -> Result<SaturatedCoefficients> {
        if theta.len() != 7 {
            return Err(Error::InvalidOption {
                option: "theta".into(),
                reason: format!(
                    "expected 7 values (r_s, a_d0, a_dd, a_q0, a_qq, a_dq, psi_f), got {}",
                    theta.len()
                ),
            });
        }
        if !(theta[0].is_finite() && theta[0] > 0.0) {
            return Err(Error::InvalidParameter {
                name: "r_s".into(),
                value: theta[0],
                reason: "must be positive and finite".into(),
            });
        }
        let magnetics = self.magnetics(theta);
        magnetics.check_usable()?;
        Ok(SaturatedCoefficients { magnetics, r_s: theta[0], h: inputs.h })
    }

    fn step(
        &self,
        c: &SaturatedCoefficients,
        inputs: &IntervalSource,
        k: usize,
        x: &[f64],
        x_next: &mut [f64],
    ) {
        let u0 = inputs.start_voltage(VoltageHold::Stator, k);
        let w_e = inputs.speeds(k).0;
        let next = saturated_step(&c.magnetics, c.r_s, [x[0], x[1]], u0, w_e, c.h, self.substeps)
            .unwrap_or([f64::NAN; 2]);
        x_next[..2].copy_from_slice(&next);
    }
}
