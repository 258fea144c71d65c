//! What a PMSM model knows besides its parameters: pole pairs, voltage hold and input, a
//! known cable resistance in series, and the reference point of the temperature estimates.
//! Shared by [`crate::pmsm::PmsmSpm`] and [`crate::pmsm::PmsmIpm`].

use crate::error::{Error, Result};
use crate::pmsm::model::interval::{VoltageHold, VoltageInput};
use crate::pmsm::model::inverter::InverterModel;
use crate::pmsm::model::temperature::ThermalReference;
use serde::{Deserialize, Serialize};

/// The setup of a PMSM model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PmsmSetup {
    /// Pole pairs n_p (`ω_e = n_p ω_m`).
    pub n_p: u32,
    /// How the voltage is held over a period.
    pub hold: VoltageHold,
    /// The voltage that drives the model.
    pub input: VoltageInput,
    /// Known resistance in series with the winding (cable, connectors) \[Ω\]: the circuit
    /// sees `R_s + R_cable`, and the estimated `r_s` is the motor's alone (MODEL.md §4).
    pub cable_resistance: f64,
    /// Reference point of the winding and magnet temperature estimates, if known.
    pub thermal: Option<ThermalReference>,
    /// The inverter's voltage error as a nuisance input (adds the parameter `v_dt`), for a
    /// model driven by the reference voltage.
    pub inverter: Option<InverterModel>,
}

impl PmsmSetup {
    /// `n_p` pole pairs and the given hold; terminal voltage, no cable, no thermal reference.
    pub fn new(n_p: u32, hold: VoltageHold) -> Self {
        Self {
            n_p,
            hold,
            input: VoltageInput::Terminal,
            cable_resistance: 0.0,
            thermal: None,
            inverter: None,
        }
    }
}

impl PmsmSetup {
    /// The resistance the circuit sees, `R_s + R_cable` \[Ω\], for the motor's `r_s`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `r_s` when it is not positive and finite, or
    /// `cable_resistance` when it is negative or not finite.
    pub fn series_resistance(&self, r_s: f64) -> Result<f64> {
        crate::pmsm::model::interval::check_positive("r_s", r_s)?;
        let cable = self.cable_resistance;
        if !(cable.is_finite() && cable >= 0.0) {
            return Err(Error::InvalidParameter {
                name: "cable_resistance".into(),
                value: cable,
                reason: "must be finite and not negative".into(),
            });
        }
        Ok(r_s + cable)
    }
}

/// Builder methods and accessors of a PMSM model with fields `setup` and `params`.
macro_rules! pmsm_model_setup {
    () => {
        /// The model for `setup` with default parameter metadata; with the inverter model
        /// the nuisance parameter `v_dt` \[V\] follows the motor's, held fixed when its value
        /// is known.
        pub fn from_setup(setup: $crate::pmsm::PmsmSetup) -> Self {
            let mut model = Self {
                setup: $crate::pmsm::PmsmSetup { inverter: None, ..setup },
                params: KIND.parameters(),
            };
            if let Some(inverter) = setup.inverter {
                model = model.with_inverter(inverter);
            }
            model
        }
        /// The same model driven by `input` (terminal voltage, or the reference with its
        /// delay and angle advance).
        pub fn with_input(mut self, input: $crate::pmsm::VoltageInput) -> Self {
            self.setup.input = input;
            self
        }
        /// The same model with a known series (cable) resistance \[Ω\]: the estimated `r_s`
        /// is then the motor's alone. A negative or non-finite value is reported by
        /// [`GreyBoxModel::coefficients`](crate::model::GreyBoxModel::coefficients).
        pub fn with_cable_resistance(mut self, ohm: f64) -> Self {
            self.setup.cable_resistance = ohm;
            self
        }
        /// The same model deriving winding and magnet temperatures from `reference`.
        pub fn with_thermal(mut self, reference: $crate::pmsm::ThermalReference) -> Self {
            self.setup.thermal = Some(reference);
            self
        }
        /// The same model with the inverter's voltage error `−v_dt tanh(i_x/w)` per phase
        /// as a nuisance input: the parameter `v_dt` \[V\] is appended to θ, held fixed when
        /// `model.known` gives its value.
        pub fn with_inverter(mut self, model: $crate::pmsm::InverterModel) -> Self {
            if self.setup.inverter.is_none() {
                self.params.push($crate::pmsm::model::inverter::v_dt_parameter());
            }
            if let Some(p) = self.params.iter_mut().find(|p| p.name == "v_dt") {
                p.fixed = model.known.is_some();
            }
            self.setup.inverter = Some(model);
            self
        }
        /// The setup (pole pairs, hold, input, cable, thermal reference, inverter).
        pub fn setup(&self) -> &$crate::pmsm::PmsmSetup {
            &self.setup
        }
        /// Pole pairs n_p.
        pub fn n_p(&self) -> u32 {
            self.setup.n_p
        }
        /// The voltage hold this model assumes.
        pub fn hold(&self) -> $crate::pmsm::VoltageHold {
            self.setup.hold
        }
        /// The voltage that drives the model.
        pub fn input(&self) -> $crate::pmsm::VoltageInput {
            self.setup.input
        }
        /// Mutable parameter metadata (bounds, fixed flags, nominal values).
        pub fn parameters_mut(&mut self) -> &mut [$crate::model::Parameter] {
            &mut self.params
        }
    };
}
pub(crate) use pmsm_model_setup;
