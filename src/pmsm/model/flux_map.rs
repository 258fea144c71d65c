//! The saturation model as a static regression through the generic trait: a measured flux
//! map's flux linkages predicted from its currents ([`FluxMapModel`]).

use crate::data::{Experiment, Values};
use crate::error::Result;
use crate::model::{DerivedEstimate, GreyBoxModel, Parameter, Sensitivities, Signal};
use crate::pmsm::model::saturation::{Saturation, SaturationExponents, saturation_parameters};

/// Channel names of a flux map: the currents `i_d`, `i_q` \[A, peak\] in, the flux linkages
/// `psi_d`, `psi_q` \[V s\] out.
pub const FLUX_MAP_CHANNELS: [&str; 4] = ["i_d", "i_q", "psi_d", "psi_q"];

/// A static model (`n_x = 0`) of a flux map: `ψ(i) = Saturation⁻¹(i; θ)`, the flux linkage
/// `[ψ_d, ψ_q]` \[V s\] at each measured current `[i_d, i_q]` \[A\], with the coefficients
/// `θ = (a_d0, a_dd, a_q0, a_qq, a_dq, ψ_f)` of [`Saturation`] and fixed exponents.
///
/// The flux is the model's inverse, solved by Newton steps ([`Saturation::flux`]); its
/// sensitivities follow from the implicit-function theorem,
/// `∂ψ/∂θ = −(∂i/∂ψ)⁻¹ ∂i/∂θ`, exactly. Fitting in flux (not current) puts the residual on
/// the quantity the map measures at set currents. Source: Hinkkanen et al., IEEE Trans.
/// Ind. Appl. 53(3) 2017 (the model); Armando et al., "Experimental identification of the
/// magnetic model of synchronous machines", IEEE Trans. Ind. Appl. 49(5) 2013 (flux maps
/// measured at constant speed).
#[derive(Clone, Debug)]
pub struct FluxMapModel {
    exponents: SaturationExponents,
    params: Vec<Parameter>,
}

impl FluxMapModel {
    /// The flux-map model with the given exponents; `nominal` sets each coefficient's scale
    /// (e.g. the start values), `SATURATION_PARAMETERS` order.
    pub fn new(exponents: SaturationExponents, nominal: &[f64; 6]) -> Self {
        let params = saturation_parameters(nominal);
        Self { exponents, params }
    }

    /// The exponents `(S, T, U, V)`.
    pub fn exponents(&self) -> SaturationExponents {
        self.exponents
    }
}

/// The currents of a flux map, shared with its experiment.
#[derive(Clone, Debug)]
pub struct FluxMapInputs {
    i_d: Values,
    i_q: Values,
}

impl GreyBoxModel for FluxMapModel {
    type Inputs = FluxMapInputs;
    type Coefficients = Saturation;

    fn name(&self) -> &str {
        "flux_map"
    }

    fn n_states(&self) -> usize {
        0
    }

    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new("psi_d", "V s"), Signal::new("psi_q", "V s")]
    }

    fn input_channels(&self) -> Vec<String> {
        vec!["i_d".into(), "i_q".into()]
    }

    fn parameters(&self) -> &[Parameter] {
        &self.params
    }

    fn derived(&self, theta: &[f64], covariance: &[Vec<f64>]) -> Vec<DerivedEstimate> {
        // The unsaturated inductances 1/a_d0, 1/a_q0 (delta method).
        let var = |j: usize| covariance.get(j).and_then(|r| r.get(j)).copied().unwrap_or(f64::NAN);
        [("l_d0", 0), ("l_q0", 2)]
            .into_iter()
            .map(|(name, j)| DerivedEstimate {
                name: name.into(),
                unit: "H".into(),
                value: 1.0 / theta[j],
                std_error: var(j).max(0.0).sqrt() / (theta[j] * theta[j]),
                ci95: None,
                experiment: None,
            })
            .collect()
    }

    fn prepare(&self, e: &Experiment) -> Result<FluxMapInputs> {
        Ok(FluxMapInputs { i_d: e.values("i_d")?.clone(), i_q: e.values("i_q")?.clone() })
    }

    fn coefficients(&self, theta: &[f64], _inputs: &FluxMapInputs) -> Result<Saturation> {
        let m = Saturation::from_theta(theta, self.exponents);
        m.check_usable()?;
        Ok(m)
    }

    fn step(&self, _c: &Saturation, _inputs: &FluxMapInputs, _k: usize, _x: &[f64], _x_next: &mut [f64]) {}

    fn output(&self, c: &Saturation, inputs: &FluxMapInputs, k: usize, _x: &[f64], y: &mut [f64]) {
        let psi = c.flux([inputs.i_d[k], inputs.i_q[k]]).unwrap_or([f64::NAN; 2]);
        y[..2].copy_from_slice(&psi);
    }

    fn sensitivities(&self) -> Option<&dyn Sensitivities<FluxMapInputs, Saturation>> {
        Some(self)
    }
}

impl Sensitivities<FluxMapInputs, Saturation> for FluxMapModel {
    fn step_sensitivity(
        &self,
        _c: &Saturation,
        _inputs: &FluxMapInputs,
        _k: usize,
        _x: &[f64],
        _s: &[f64],
        _x_next: &mut [f64],
        _s_next: &mut [f64],
    ) {
    }

    fn output_sensitivity(
        &self,
        c: &Saturation,
        inputs: &FluxMapInputs,
        k: usize,
        _x: &[f64],
        _s: &[f64],
        dy: &mut [f64],
    ) {
        let n_theta = self.params.len();
        let Ok(psi) = c.flux([inputs.i_d[k], inputs.i_q[k]]) else {
            dy.fill(f64::NAN);
            return;
        };
        let d = c.derivatives(psi);
        let g = d.gamma;
        let det = g[0][0] * g[1][1] - g[0][1] * g[1][0];
        for (j, di) in d.d_theta.iter().enumerate().take(n_theta) {
            // −Γ⁻¹ ∂i/∂θ_j
            dy[j] = -(g[1][1] * di[0] - g[0][1] * di[1]) / det;
            dy[n_theta + j] = -(g[0][0] * di[1] - g[1][0] * di[0]) / det;
        }
    }
}
