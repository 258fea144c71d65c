//! The locked-rotor (standstill) model: the stator circuit without back-EMF, as drive
//! firmware identifies it at power-up (ODrive's resistance and inductance measurement,
//! VESC's and moteus' `R`/`L` detection): per excited axis
//! `L_x di_x/dt = u_x − R_s(T) i_x + V_dt e_x(i)` at `ω = 0` (MODEL.md §1 with `ω_e = 0`,
//! §4 for the inverter's error `e`), sampled exactly for a voltage held over the period.

use crate::data::{Experiment, Values};
use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Parameter, Signal};
use crate::pmsm::log::transform::{clarke, inverse_clarke, inverse_park, park};

/// Name of the winding-temperature channel \[°C\] a standstill log may carry.
pub const WINDING_TEMPERATURE: &str = "t_winding";

/// How the standstill model reads a log.
#[derive(Clone, Debug, PartialEq)]
pub struct StandstillSetup {
    /// Pole pairs n_p (the dead-time error's direction needs `θ_e = n_p θ_m`).
    pub pole_pairs: u32,
    /// The excited axes, `0` = d, `1` = q (each gets its inductance and its current output).
    pub axes: Vec<usize>,
    /// `Some(d)`: the voltage is the controller's reference `ud_ref, uq_ref`, applied `d`
    /// samples later and short of it by the inverter's error, whose `v_dt` \[V\] (and width)
    /// is then estimated; `None`: the measured terminal voltage `ud, uq` (no inverter error in it).
    pub reference_delay: Option<usize>,
    /// Width w \[A\] of the inverter error's smooth sign `tanh(i_x/w)`: `Some` held at this
    /// value, `None` estimated (parameter `width`, with the reference voltage).
    pub width: Option<f64>,
    /// `Some((T_0, α))`: `R_s(T) = r_s (1 + α (T − T_0))` with the log's
    /// [`WINDING_TEMPERATURE`] channel, `r_s` the resistance at `T_0` \[°C\], α \[1/K\];
    /// `None`: one resistance.
    pub temperature: Option<(f64, f64)>,
}

/// The standstill model: states and outputs the excited axes' currents \[A\]; parameters
/// `r_s` \[Ω\] (at `T_0` with a temperature channel), `l_d` and/or `l_q` \[H\], and `v_dt`
/// \[V\] (with the reference voltage). The exact step of `L di/dt = u − R i` with `u` held
/// over `[t_k, t_{k+1})`: `i[k+1] = a i[k] + (1 − a) u/R`, `a = exp(−R h / L)`; the
/// inverter error is that of the model's phase currents at `t_k` (its state), held over the
/// period, with the smooth sign's width estimated (parameter `width` \[A\]) unless given.
///
/// Source: the voltage-equation of MODEL.md §1 at standstill; dead-time model MODEL.md §4
/// (Choi & Sul, IEEE Trans. Power Electron. 11(2) 1996); the test as in drive firmware
/// (ODrive `measure_phase_resistance`/`measure_phase_inductance`).
#[derive(Clone, Debug)]
pub struct StandstillModel {
    setup: StandstillSetup,
    params: Vec<Parameter>,
}

/// The per-sample data of a standstill log.
#[derive(Clone, Debug)]
pub struct StandstillInputs {
    h: f64,
    /// The applied (delayed) voltage per axis \[V\].
    u: [Vec<f64>; 2],
    /// The measured currents per axis \[A\] (those of an axis not modelled stand in for its
    /// state in the inverter error).
    i: [Vec<f64>; 2],
    /// The electrical angle `θ_e = n_p θ_m` \[rad\] (0 without the reference voltage).
    theta_e: Vec<f64>,
    /// `1 + α (T[k] − T_0)` per sample, when a temperature channel is used.
    factor: Option<Vec<f64>>,
}

impl StandstillInputs {
    /// Of axis `axis` at sample `k`: the applied voltage \[V\], the inverter error's
    /// direction per unit `V_dt` of the measured currents with width `width` \[A\], the
    /// resistance's temperature factor.
    pub(crate) fn at(&self, axis: usize, k: usize, width: f64) -> (f64, f64, f64) {
        let e = error_direction([self.i[0][k], self.i[1][k]], self.theta_e[k], width);
        (self.u[axis][k], e[axis], self.factor.as_ref().map_or(1.0, |f| f[k]))
    }
}

/// `(r_s, [l_d, l_q], v_dt, width)` of a parameter vector.
#[derive(Clone, Copy, Debug)]
pub struct StandstillCoefficients {
    r_s: f64,
    l: [f64; 2],
    v_dt: f64,
    width: f64,
}

const AXIS_NAMES: [(&str, &str); 2] = [("l_d", "id"), ("l_q", "iq")];

impl StandstillModel {
    /// The model of `setup`; `nominal` = `[r_s, l_d, l_q, v_dt, width]` sets the parameters'
    /// scales.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (`axes`) for no axis or an axis other than 0, 1;
    /// (`width`) for a width that is not positive and finite.
    pub fn new(setup: StandstillSetup, nominal: [f64; 5]) -> Result<Self> {
        if setup.axes.is_empty() || setup.axes.iter().any(|a| *a > 1) {
            return Err(Error::InvalidOption {
                option: "axes".into(),
                reason: format!("{:?}: give 0 (d), 1 (q) or both", setup.axes),
            });
        }
        if let Some(w) = setup.width.filter(|w| !(*w > 0.0 && w.is_finite())) {
            return Err(Error::InvalidOption {
                option: "width".into(),
                reason: format!("{w} A: the smooth sign's width must be positive"),
            });
        }
        let mut params = vec![Parameter::positive("r_s", "Ω", nominal[0])];
        params.extend(setup.axes.iter().map(|&a| Parameter::positive(AXIS_NAMES[a].0, "H", nominal[1 + a])));
        if setup.reference_delay.is_some() {
            params.push(Parameter { lower: 0.0, ..Parameter::free("v_dt", "V", nominal[3]) });
            if setup.width.is_none() {
                params.push(Parameter::positive("width", "A", nominal[4]));
            }
        }
        Ok(Self { setup, params })
    }

    /// The setup.
    pub fn setup(&self) -> &StandstillSetup {
        &self.setup
    }

    fn unpack(&self, theta: &[f64]) -> StandstillCoefficients {
        let mut l = [f64::NAN; 2];
        for (j, &a) in self.setup.axes.iter().enumerate() {
            l[a] = theta[1 + j];
        }
        let j = 1 + self.setup.axes.len();
        let v_dt = if self.setup.reference_delay.is_some() { theta[j] } else { 0.0 };
        let width = self.setup.width.unwrap_or_else(|| theta.get(j + 1).copied().unwrap_or(1.0));
        StandstillCoefficients { r_s: theta[0], l, v_dt, width }
    }
}

/// The inverter error's dq direction per unit `V_dt` of the dq current `i` \[A\] at the
/// electrical angle `theta_e` \[rad\]: `park(clarke(−tanh(i_a/w), −tanh(i_b/w),
/// −tanh(i_c/w)), θ_e)` of its phase currents (MODEL.md §4).
fn error_direction(i: [f64; 2], theta_e: f64, width: f64) -> [f64; 2] {
    let s = |x: f64| -(x / width).tanh();
    let (al, be) = inverse_park(i[0], i[1], theta_e);
    let (a, b, c) = inverse_clarke(al, be);
    let (ea, eb) = clarke(s(a), s(b), s(c));
    let (ed, eq) = park(ea, eb, theta_e);
    [ed, eq]
}

impl GreyBoxModel for StandstillModel {
    type Inputs = StandstillInputs;
    type Coefficients = StandstillCoefficients;

    fn name(&self) -> &str {
        "standstill"
    }

    fn n_states(&self) -> usize {
        self.setup.axes.len()
    }

    fn outputs(&self) -> Vec<Signal> {
        self.setup.axes.iter().map(|&a| Signal::new(AXIS_NAMES[a].1, "A")).collect()
    }

    fn input_channels(&self) -> Vec<String> {
        let mut c: Vec<String> = match self.setup.reference_delay {
            Some(_) => vec!["ud_ref".into(), "uq_ref".into(), "theta_m".into()],
            None => vec!["ud".into(), "uq".into()],
        };
        if self.setup.temperature.is_some() {
            c.push(WINDING_TEMPERATURE.into());
        }
        c
    }

    fn parameters(&self) -> &[Parameter] {
        &self.params
    }

    fn advice(&self, name: &str) -> Option<String> {
        match name {
            "v_dt" => Some(
                "the inverter error is a constant offset unless the current takes levels of both signs and at least \
                 two magnitudes: inject steps of ± two levels"
                    .into(),
            ),
            "l_d" | "l_q" => Some("inject voltage steps (the current's transients carry the inductance)".into()),
            _ => None,
        }
    }

    fn prepare(&self, e: &Experiment) -> Result<StandstillInputs> {
        let n = e.len();
        let u = match self.setup.reference_delay {
            Some(d) => [delayed(e.channel("ud_ref")?, d), delayed(e.channel("uq_ref")?, d)],
            None => [e.channel("ud")?.to_vec(), e.channel("uq")?.to_vec()],
        };
        let theta_e = match self.setup.reference_delay {
            Some(_) => e.channel("theta_m")?.iter().map(|t| f64::from(self.setup.pole_pairs) * t).collect(),
            None => vec![0.0; n],
        };
        let i = [e.channel("id")?.to_vec(), e.channel("iq")?.to_vec()];
        let factor = match self.setup.temperature {
            Some((t0, alpha)) => {
                let t: &Values = e.values(WINDING_TEMPERATURE)?;
                Some((0..n).map(|k| 1.0 + alpha * (t[k] - t0)).collect())
            }
            None => None,
        };
        Ok(StandstillInputs { h: e.h(), u, i, theta_e, factor })
    }

    fn coefficients(&self, theta: &[f64], _inputs: &StandstillInputs) -> Result<StandstillCoefficients> {
        Ok(self.unpack(theta))
    }

    fn step(
        &self,
        c: &StandstillCoefficients,
        inputs: &StandstillInputs,
        k: usize,
        x: &[f64],
        x_next: &mut [f64],
    ) {
        let r = c.r_s * inputs.factor.as_ref().map_or(1.0, |f| f[k]);
        // The inverter error of the modelled current (the state: the true current the
        // inverter sees, not the noisy measurement), the measured one on an axis not modelled.
        let mut i = [inputs.i[0][k], inputs.i[1][k]];
        for (j, &a) in self.setup.axes.iter().enumerate() {
            i[a] = x[j];
        }
        let e = if c.v_dt != 0.0 { error_direction(i, inputs.theta_e[k], c.width) } else { [0.0; 2] };
        for (j, &a) in self.setup.axes.iter().enumerate() {
            let u = inputs.u[a][k] + c.v_dt * e[a];
            let decay = (-r * inputs.h / c.l[a]).exp();
            x_next[j] = decay * x[j] + (1.0 - decay) * u / r;
        }
    }
}

/// The reference `c` \[V\] as the motor receives it `d` samples later: `c[k − d]`, and 0
/// before the first arrives (a standstill test starts at rest). Length of `c`.
pub(crate) fn delayed(c: &[f64], d: usize) -> Vec<f64> {
    (0..c.len()).map(|k| if k >= d { c[k - d] } else { 0.0 }).collect()
}
