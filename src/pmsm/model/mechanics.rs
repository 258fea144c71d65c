//! The mechanics behind the shaft as a static regression through the generic trait: the
//! speed change over a window predicted from the integrals of the torques acting in it
//! ([`MechanicsModel`]).
//!
//! `J dω_m/dt = T_e − B ω_m − T_c tanh(ω_m/ω_c) − m g l sin θ_m − T_0 − T_L(t)` integrated
//! over a window `[t_a, t_b]`:
//! `J (ω_m(t_b) − ω_m(t_a)) = X_T − B X_ω − T_c X_c − m g l X_g − T_0 X_1 − X_L`, with
//! `X_T = ∫T_e`, `X_ω = ∫ω_m`, `X_c = ∫tanh(ω_m/ω_c)`, `X_g = ∫sin θ_m`, `X_1 = t_b − t_a`,
//! `X_L = ∫T_L`. Integrating instead of differentiating keeps the speed noise out of the
//! regressors (it enters only the two ends of `Δω`), which is why the windows, not the
//! samples, are the observations (the integral method of system identification: Young,
//! *Recursive Estimation and Time-Series Analysis*, 2nd ed. 2011, ch. 8; Gawthrop,
//! "Continuous-time identification", in Garnier & Wang (eds.) 2008).

use crate::data::{Experiment, Values};
use crate::error::Result;
use crate::model::{DerivedEstimate, GreyBoxModel, Parameter, Sensitivities, Signal};

/// Channels of a window experiment: the output `dw` \[rad/s\], then the regressors `x_t`
/// \[N m s\], `x_w` \[rad\], `x_c` \[s\], `x_g` \[s\], `x_1` \[s\], `x_l` \[N m s\].
pub const MECHANICS_CHANNELS: [&str; 7] = ["dw", "x_t", "x_w", "x_c", "x_g", "x_1", "x_l"];

/// Which torques the mechanical model has besides inertia, viscous and Coulomb friction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct MechanicsTerms {
    /// A gravity load `m g l sin θ_m` (parameter `mgl` \[N m\]; an arm whose angle is 0
    /// hanging down).
    pub gravity: bool,
    /// A constant load torque (parameter `t_0` \[N m\]; a vertical axis' weight, a constant
    /// process force).
    pub constant: bool,
}

impl MechanicsTerms {
    /// The [`MECHANICS_CHANNELS`] indices of the regressors of the parameters after `j`, in
    /// parameter order: `x_w` (`b`), `x_c` (`t_c`), then `x_g` (`mgl`) and `x_1` (`t_0`) as
    /// asked.
    pub(crate) fn loss_channels(self) -> Vec<usize> {
        let mut c = vec![2, 3];
        if self.gravity {
            c.push(4);
        }
        if self.constant {
            c.push(5);
        }
        c
    }
}

/// The axis whose motion the mechanics describe: the motor's shaft, or a linear axis the
/// shaft drives (a ball screw, a rack, a belt) or a linear motor moves.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Axis {
    /// The shaft: `J dω_m/dt = T_e − …`, parameters in kg m², N m s/rad, N m.
    #[default]
    Rotary,
    /// A linear axis of `lead` \[m\] of travel per revolution of the logs' shaft angle
    /// (a ball screw's lead over a gear ratio; a linear motor of pole pitch `τ_p` read as a
    /// shaft of `n_p` pole pairs: `2 n_p τ_p`): `m dv/dt = F − b v − f_c tanh(v/v_c) − f_0 −
    /// F_L`, with `v = ω_m lead/(2π)` \[m/s\] and `F = T_e 2π/lead` \[N\] (the transmission
    /// lossless and stiff: its losses are in the friction), parameters in kg, N s/m, N
    /// (`m = J (2π/lead)²` for the inertia reflected to the axis: a stiff, lossless
    /// transmission keeps the kinetic energy, `J ω²/2 = m v²/2`, and the power, `T ω = F v`).
    Linear {
        /// Travel per shaft revolution \[m\].
        lead: f64,
    },
}

impl Axis {
    /// Radians of the shaft per unit of the axis' travel: 1 (rotary) or `2π/lead` \[rad/m\].
    pub fn radians_per_unit(self) -> f64 {
        match self {
            Self::Rotary => 1.0,
            Self::Linear { lead } => std::f64::consts::TAU / lead,
        }
    }

    /// Whether this is the shaft (serde skips the default).
    pub fn is_rotary(&self) -> bool {
        *self == Self::Rotary
    }

    /// The faults of a linear axis with `terms`: a lead that is not positive and finite
    /// (`axis`), a gravity term (`gravity`: a linear axis' weight is a constant force,
    /// [`MechanicsTerms::constant`]). The shaft has none.
    ///
    /// # Errors
    /// [`crate::Error::InvalidOption`] naming the option.
    pub fn check(self, terms: MechanicsTerms) -> Result<()> {
        let Self::Linear { lead } = self else { return Ok(()) };
        let invalid =
            |option: &str, reason: String| crate::Error::InvalidOption { option: option.into(), reason };
        if !(lead.is_finite() && lead > 0.0) {
            return Err(invalid(
                "axis",
                format!("a lead of {lead} m: the travel per revolution must be positive and finite"),
            ));
        }
        if terms.gravity {
            return Err(invalid(
                "gravity",
                "a linear axis' weight is a constant force along it: the constant load (--constant-load), not an \
                 arm's gravity"
                    .into(),
            ));
        }
        Ok(())
    }

    /// Names and units of `[inertia, viscous, Coulomb, gravity, constant load]` (the gravity
    /// load is the shaft's only) and the speed's unit.
    pub fn names(self) -> ([(&'static str, &'static str); 5], &'static str) {
        match self {
            Self::Rotary => (
                [("j", "kg m^2"), ("b", "N m s/rad"), ("t_c", "N m"), ("mgl", "N m"), ("t_0", "N m")],
                "rad/s",
            ),
            Self::Linear { .. } => {
                ([("m", "kg"), ("b", "N s/m"), ("f_c", "N"), ("mgl", "N m"), ("f_0", "N")], "m/s")
            }
        }
    }
}

/// The window model: `Δω = (X_T − X_L − b X_ω − t_c X_c − mgl X_g − t_0 X_1) / j` per
/// window, parameters `j` \[kg m²\], `b` \[N m s/rad\], `t_c` \[N m\], then `mgl` \[N m\] and
/// `t_0` \[N m\] as [`MechanicsTerms`] asks; on a linear [`Axis`] the same in the axis'
/// units (`m` \[kg\], `b` \[N s/m\], `f_c` \[N\], `f_0` \[N\]; no gravity load). Linear in
/// all but the inertia; exact sensitivities.
#[derive(Clone, Debug)]
pub struct MechanicsModel {
    terms: MechanicsTerms,
    params: Vec<Parameter>,
    /// [`MechanicsTerms::loss_channels`], fixed with the terms.
    loss: Vec<usize>,
    /// The speed's unit.
    speed_unit: &'static str,
}

impl MechanicsModel {
    /// The model of the shaft with `terms`; `nominal` = `[j, b, t_c, mgl, t_0]` sets the
    /// parameters' scales (non-zero magnitudes).
    pub fn new(terms: MechanicsTerms, nominal: [f64; 5]) -> Self {
        Self::on_axis(terms, nominal, Axis::Rotary)
    }

    /// The model on `axis` (names and units of [`Axis::names`]); `nominal` as in
    /// [`Self::new`], in the axis' units. A gravity term on a linear axis is left out: its
    /// weight is a constant force ([`MechanicsTerms::constant`]).
    pub fn on_axis(terms: MechanicsTerms, nominal: [f64; 5], axis: Axis) -> Self {
        let terms = MechanicsTerms { gravity: terms.gravity && axis.is_rotary(), ..terms };
        let scale = |x: f64| if x.abs() > 0.0 && x.is_finite() { x.abs() } else { 1.0 };
        let (names, speed_unit) = axis.names();
        let [(j, ju), (b, bu), (c, cu), (g, gu), (t0, t0u)] = names;
        let mut params = vec![
            Parameter::positive(j, ju, scale(nominal[0])),
            Parameter::free(b, bu, scale(nominal[1])),
            Parameter::free(c, cu, scale(nominal[2])),
        ];
        if terms.gravity {
            params.push(Parameter::free(g, gu, scale(nominal[3])));
        }
        if terms.constant {
            params.push(Parameter::free(t0, t0u, scale(nominal[4])));
        }
        Self { terms, params, loss: terms.loss_channels(), speed_unit }
    }

    /// The terms.
    pub fn terms(&self) -> MechanicsTerms {
        self.terms
    }
}

/// The regressors of a window experiment, shared with it (`x_t, x_w, x_c, x_g, x_1, x_l`).
#[derive(Clone, Debug)]
pub struct MechanicsInputs {
    x: Vec<Values>,
}

impl MechanicsInputs {
    /// Of window `k`: the driving impulse `X_T − X_L` \[N m s\].
    fn drive(&self, k: usize) -> f64 {
        self.x[0][k] - self.x[5][k]
    }

    /// Of window `k`: the regressor of [`MECHANICS_CHANNELS`] index `channel` (≥ 1).
    fn regressor(&self, channel: usize, k: usize) -> f64 {
        self.x[channel - 1][k]
    }
}

impl GreyBoxModel for MechanicsModel {
    type Inputs = MechanicsInputs;
    type Coefficients = Vec<f64>;

    fn name(&self) -> &str {
        "mechanics"
    }

    fn n_states(&self) -> usize {
        0
    }

    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new("dw", self.speed_unit)]
    }

    fn input_channels(&self) -> Vec<String> {
        MECHANICS_CHANNELS[1..].iter().map(|s| (*s).to_string()).collect()
    }

    fn parameters(&self) -> &[Parameter] {
        &self.params
    }

    fn advice(&self, name: &str) -> Option<String> {
        match name {
            "b" | "t_c" | "f_c" => Some(
                "viscous and Coulomb friction separate only over a range of speeds of both signs: move at \
                 several speeds"
                    .into(),
            ),
            "mgl" => Some("the gravity load needs the angle to move over a good part of a turn".into()),
            "t_0" | "f_0" => {
                Some("a constant load and the gravity load separate only over a wide range of angles".into())
            }
            "j" | "m" => Some("inertia needs accelerations: start, stop and reverse".into()),
            _ => None,
        }
    }

    fn derived(&self, theta: &[f64], covariance: &[Vec<f64>]) -> Vec<DerivedEstimate> {
        // The mechanical time constant J/B (delta method), when B > 0.
        let var = |i: usize, j: usize| covariance.get(i).and_then(|r| r.get(j)).copied().unwrap_or(f64::NAN);
        let (j, b) = (theta[0], theta[1]);
        if b <= 0.0 {
            return Vec::new();
        }
        let tau = j / b;
        let (dj, db) = (1.0 / b, -j / (b * b));
        let v = dj * dj * var(0, 0) + 2.0 * dj * db * var(0, 1) + db * db * var(1, 1);
        vec![DerivedEstimate {
            name: "tau_m".into(),
            unit: "s".into(),
            value: tau,
            std_error: v.max(0.0).sqrt(),
            ci95: None,
            experiment: None,
        }]
    }

    fn prepare(&self, e: &Experiment) -> Result<MechanicsInputs> {
        let x = MECHANICS_CHANNELS[1..].iter().map(|c| e.values(c).cloned()).collect::<Result<Vec<_>>>()?;
        Ok(MechanicsInputs { x })
    }

    fn coefficients(&self, theta: &[f64], _inputs: &MechanicsInputs) -> Result<Vec<f64>> {
        Ok(theta.to_vec())
    }

    fn step(&self, _c: &Vec<f64>, _inputs: &MechanicsInputs, _k: usize, _x: &[f64], _x_next: &mut [f64]) {}

    fn output(&self, c: &Vec<f64>, inputs: &MechanicsInputs, k: usize, _x: &[f64], y: &mut [f64]) {
        let losses: f64 = self.loss.iter().zip(&c[1..]).map(|(&ch, p)| p * inputs.regressor(ch, k)).sum();
        y[0] = (inputs.drive(k) - losses) / c[0];
    }

    fn sensitivities(&self) -> Option<&dyn Sensitivities<MechanicsInputs, Vec<f64>>> {
        Some(self)
    }
}

impl Sensitivities<MechanicsInputs, Vec<f64>> for MechanicsModel {
    fn step_sensitivity(
        &self,
        _c: &Vec<f64>,
        _inputs: &MechanicsInputs,
        _k: usize,
        _x: &[f64],
        _s: &[f64],
        _x_next: &mut [f64],
        _s_next: &mut [f64],
    ) {
    }

    fn output_sensitivity(
        &self,
        c: &Vec<f64>,
        inputs: &MechanicsInputs,
        k: usize,
        x: &[f64],
        _s: &[f64],
        dy: &mut [f64],
    ) {
        let mut y = [0.0];
        self.output(c, inputs, k, x, &mut y);
        dy[0] = -y[0] / c[0];
        for (j, &ch) in self.loss.iter().enumerate() {
            dy[1 + j] = -inputs.regressor(ch, k) / c[0];
        }
    }
}
