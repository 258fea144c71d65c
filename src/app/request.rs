//! What a user asks of a fit, typed ([`FitRequest`]): the options of `greybox fit` and of
//! the Python `fit`, without their spelling (flags, keywords) and without the outputs each
//! writes. The command line converts its flags into one, Python its keywords; [`super::plan`]
//! turns it into the library's options.

use super::values::{
    Advance, DeadTime, Delay, Gain, InverterChoice, LegWidth, Method, ModelChoice, Pll, PolePairs, Voltage,
};
use crate::error::{Error, Result};
use crate::estimate::{PrecisionTarget, ScalingKind, SolverKind, Tolerances, WeightingKind};
use crate::pmsm::{CarrierEdge, CsvOptions, DeadTimeMask, HoldChoice, Modulator, PwmInverter, PwmUpdate};
use std::path::PathBuf;

/// How the logs are read: the reader's options (columns, units, frames, window, limits)
/// and whether each log is split at the gaps of its time column into segments.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LogReading {
    /// The reader's options (pole pairs `None`: the fit sets them).
    pub csv: CsvOptions,
    /// Split each log at its gaps into segments fitted jointly (`LOG#1`, `LOG#2`, …).
    pub split_gaps: bool,
}

/// A fit as asked for: every option of `greybox fit` that changes the fit (not its
/// outputs), typed, with the command line's defaults ([`FitRequest::new`]). Units SI.
#[derive(Clone, Debug, PartialEq)]
pub struct FitRequest {
    /// Pole pairs n_p, or chosen from the data.
    pub pole_pairs: PolePairs,
    /// The machine model and its equations.
    pub model: ModelChoice,
    /// The drive's control (PWM) period \[s\] for the steady-state equations.
    pub control_period: Option<f64>,
    /// The accuracy a trusted fit must reach ([`crate::pmsm::PmsmFitOptions::precision`]):
    /// `None` the fit's default, `Some(vec![])` none.
    pub precision: Option<Vec<PrecisionTarget>>,
    /// The voltage hold between samples.
    pub hold: HoldChoice,
    /// The voltage that drives the model.
    pub voltage: Voltage,
    /// The reference's computational delay \[samples\].
    pub delay: Delay,
    /// The modulator's angle advance \[ω_e h\].
    pub advance: Advance,
    /// The controller's speed estimate: a bandwidth \[rad/s\], searched, or the logged
    /// speed; `None`: the logged speed, searched with the PWM inverter.
    pub speed_pll: Option<Pll>,
    /// The averaged dead-time model.
    pub dead_time: DeadTime,
    /// The averaged model's sign width \[A\], or searched; `None`: 2 % of the peak current.
    pub dead_time_width: Option<Pll>,
    /// The averaged model's mask of zero crossings.
    pub dead_time_mask: Option<DeadTimeMask>,
    /// DC-link voltage \[V\] (`None`: a column `u_dc` where the PWM inverter needs one).
    pub u_dc: Option<f64>,
    /// Known series resistance of cable and connectors \[Ω\].
    pub cable_resistance: f64,
    /// Reference temperature T_0 \[°C\] of `r_s0` and `psi_f0`.
    pub t0: Option<f64>,
    /// Winding resistance at T_0 \[Ω\].
    pub r_s0: Option<f64>,
    /// Magnet flux at T_0 \[V s\].
    pub psi_f0: Option<f64>,
    /// Start values in model order (SI); `None`: linear least squares.
    pub start: Option<Vec<f64>>,
    /// Parameters held fixed: name, and a value (or `None`: at the start value).
    pub fix: Vec<(String, Option<f64>)>,
    /// Parameters estimated per log.
    pub per_log: Vec<String>,
    /// The optimiser.
    pub solver: SolverKind,
    /// The parameter scaling.
    pub scaling: ScalingKind,
    /// k-step-ahead horizon \[samples\]; `None`: output error.
    pub horizon: Option<usize>,
    /// Sample weighting β(ω) (thesis eq. 5.11).
    pub weighting: WeightingKind,
    /// Huber's constant C (δ = C σ̂); `None`: least squares.
    pub huber: Option<f64>,
    /// Output weights Λ of i_d, i_q.
    pub output_weights: Option<Vec<f64>>,
    /// Bounds: name, low, high (SI).
    pub bounds: Vec<(String, f64, f64)>,
    /// The first measured currents as the exact initial state.
    pub fixed_x0: bool,
    /// Low-pass prefilter cutoff \[Hz\].
    pub prefilter: Option<f64>,
    /// The estimation method.
    pub method: Method,
    /// The solver's tolerances and iteration limit.
    pub tolerances: Tolerances,
    /// Whether an unconverged or untrusted fit counts as a success (exit 0).
    pub allow_unconverged: bool,
    /// How the logs are read.
    pub reading: LogReading,
    /// The switching-resolved PWM inverter.
    pub pwm: PwmRequest,
    /// The outputs asked for that need simulated currents (a plot, the residuals), named
    /// as the caller names them (`--plot`): refused with the methods that simulate none.
    pub simulated_outputs: Vec<String>,
}

impl FitRequest {
    /// The defaults of `greybox fit -p N` (and of the Python `fit`) with `pole_pairs`.
    pub fn new(pole_pairs: PolePairs) -> Self {
        Self {
            pole_pairs,
            model: ModelChoice::Spm,
            control_period: None,
            precision: None,
            hold: HoldChoice::Auto,
            voltage: Voltage::Actual,
            delay: Delay::Samples(1),
            advance: Advance::Value(1.5),
            speed_pll: None,
            dead_time: DeadTime::None,
            dead_time_width: None,
            dead_time_mask: None,
            u_dc: None,
            cable_resistance: 0.0,
            t0: None,
            r_s0: None,
            psi_f0: None,
            start: None,
            fix: Vec::new(),
            per_log: Vec::new(),
            solver: SolverKind::Auto,
            scaling: ScalingKind::Nominal,
            horizon: None,
            weighting: WeightingKind::Uniform,
            huber: None,
            output_weights: None,
            bounds: Vec::new(),
            fixed_x0: false,
            prefilter: None,
            method: Method::Auto,
            tolerances: Tolerances::default(),
            allow_unconverged: false,
            reading: LogReading::default(),
            pwm: PwmRequest::default(),
            simulated_outputs: Vec::new(),
        }
    }
}

/// The switching-resolved PWM inverter as asked for (`--inverter pwm` and its options).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PwmRequest {
    /// None, or the PWM inverter.
    pub inverter: InverterChoice,
    /// The modulator's zero sequence.
    pub modulator: Modulator,
    /// Duty-ratio updates per carrier period.
    pub pwm_update: PwmUpdate,
    /// Carrier frequency \[Hz\]; `None`: from the sample time.
    pub carrier_hz: Option<f64>,
    /// PWM counter levels per half carrier period; `None`: continuous.
    pub pwm_levels: Option<u32>,
    /// The carrier's direction over the first period; `None`: chosen from the data.
    pub carrier_first: Option<CarrierEdge>,
    /// Width i_w of the smooth leg state; `None`: estimated.
    pub leg_state_width: Option<LegWidth>,
    /// Gain k_o of the one-step predictor; `None`: 1.
    pub predictor_gain: Option<Gain>,
    /// A JSON file of known inverter parameters (t_d, u_th, r_on, i_w).
    pub inverter_params: Option<PathBuf>,
}

impl PwmRequest {
    /// The inverter asked for at DC link `u_dc` \[V\] (`None`: a column `u_dc`); `None`
    /// without the PWM inverter.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming the PWM option given without `--inverter pwm`, or an
    /// unreadable `--inverter-params` file or key.
    pub fn inverter(&self, u_dc: Option<f64>) -> Result<Option<PwmInverter>> {
        if self.inverter == InverterChoice::None {
            let stray = [
                ("--carrier-hz", self.carrier_hz.is_some()),
                ("--pwm-levels", self.pwm_levels.is_some()),
                ("--carrier-first", self.carrier_first.is_some()),
                ("--leg-state-width", self.leg_state_width.is_some()),
                ("--inverter-params", self.inverter_params.is_some()),
                ("--predictor-gain", self.predictor_gain.is_some()),
                ("--modulator", self.modulator != Modulator::MinMax),
                ("--pwm-update", self.pwm_update != PwmUpdate::Double),
            ];
            if let Some((flag, _)) = stray.iter().find(|(_, given)| *given) {
                return Err(Error::InvalidOption {
                    option: flag.trim_start_matches('-').into(),
                    reason: format!("{flag} describes the PWM inverter: add --inverter pwm"),
                });
            }
            return Ok(None);
        }
        let mut inv = PwmInverter {
            u_dc,
            carrier_hz: self.carrier_hz,
            modulator: self.modulator,
            update: self.pwm_update,
            levels: self.pwm_levels,
            first_edge: self.carrier_first,
            predictor_gain: match self.predictor_gain {
                Some(Gain::Value(g)) => Some(g),
                Some(Gain::Estimate) => None,
                None => Some(1.0),
            },
            ..PwmInverter::default()
        };
        match self.leg_state_width {
            Some(LegWidth::Amperes(w)) => inv.i_w = Some(w),
            Some(LegWidth::Estimate) | None => inv.estimate_i_w = true,
            Some(LegWidth::Sign) => {}
        }
        if let Some(path) = &self.inverter_params {
            known_parameters(path, &mut inv)?;
        }
        Ok(Some(inv))
    }
}

/// Reads the known inverter parameters of `path` into `inv`.
fn known_parameters(path: &PathBuf, inv: &mut PwmInverter) -> Result<()> {
    let bad = |reason: String| Error::InvalidOption { option: "inverter-params".into(), reason };
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("{}: {e}", path.display())))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(format!("{}: not JSON ({e})", path.display())))?;
    let value = |key: &str| -> Option<f64> {
        json.get(key).and_then(serde_json::Value::as_f64).or_else(|| {
            json.get("parameters")?
                .as_array()?
                .iter()
                .find(|p| p.get("name").and_then(|n| n.as_str()) == Some(key))?
                .get("value")?
                .as_f64()
        })
    };
    let mut found = 0;
    for (key, slot) in [("t_d", &mut inv.t_d), ("u_th", &mut inv.u_th), ("i_w", &mut inv.i_w)] {
        if let Some(v) = value(key) {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(format!("{}: {key} = {v} must be finite and not negative", path.display())));
            }
            *slot = Some(v);
            found += 1;
        }
    }
    if inv.i_w.is_some() {
        inv.estimate_i_w = false;
    }
    if let Some(r) = value("r_on") {
        if !(r.is_finite() && r >= 0.0) {
            return Err(bad(format!("{}: r_on = {r} must be finite and not negative", path.display())));
        }
        inv.r_on = r;
        found += 1;
    }
    if found == 0 {
        return Err(bad(format!(
            "{}: none of t_d [s], u_th [V], r_on [Ω], i_w [A] found (as keys or in `parameters`)",
            path.display()
        )));
    }
    Ok(())
}
