//! The options of a PMSM fit ([`PmsmFitOptions`], [`HoldChoice`]), the one struct every
//! step of [`crate::pmsm::fit_pmsm`] reads, and how they configure a model's parameters.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{FitResult, PemOptions, PrecisionTarget};
use crate::model::Parameter;
use crate::pmsm::log::Scale;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::inverter::InverterModel;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::pwm::PwmInverter;
use crate::pmsm::model::temperature::ThermalReference;
use serde::{Deserialize, Serialize};

/// The report of a nested fit of other logs or options (`None` when it fails): for the
/// checks that confirm a suspected setup mistake by fitting the log as the mistake would
/// have it, and the check that the log's parts agree ([`crate::pmsm::checks`]' segment
/// check); given by the workflow above them ([`crate::pmsm::fit_pmsm`]), so the checks need
/// not know it.
pub(crate) type RefitReport<'a> = &'a (dyn Fn(&[Experiment], &PmsmFitOptions) -> Option<FitResult> + Sync);

impl PmsmFitOptions {
    /// The motor's parameters of `fit` in its kind's order (MODEL.md §2: `r_s, l_s, k_e` or
    /// `r_s, l_d, l_q, k_e`; Ω, H, V s/rad) with the whole series resistance, `r_s` plus
    /// [`cable_resistance`](Self::cable_resistance), as the voltage equations see it; `None`
    /// when `fit` lacks one.
    pub(crate) fn series_theta(&self, fit: &FitResult) -> Option<Vec<f64>> {
        self.model
            .parameter_names()
            .iter()
            .map(|n| {
                fit.parameter(n).map(|p| p.value + if *n == "r_s" { self.cable_resistance } else { 0.0 })
            })
            .collect()
    }
}

/// How many times lower than `loss` a nested fit of `experiments` with `other` is
/// ([`nested_loss`]), when it is more than `ratio` times lower: a suspected setup mistake
/// confirmed. `None` otherwise or when it fails.
pub(crate) fn confirmed(
    refit: RefitReport<'_>,
    experiments: &[Experiment],
    other: PmsmFitOptions,
    loss: f64,
    ratio: f64,
) -> Option<f64> {
    let alt = nested_loss(refit, experiments, other)?;
    (alt * ratio < loss).then(|| loss / alt)
}

/// The loss of a nested fit of `experiments` with `other` as a suspected mistake would have
/// it: from the least-squares start, without setup checks of its own; `None` when it fails.
pub(crate) fn nested_loss(
    refit: RefitReport<'_>,
    experiments: &[Experiment],
    other: PmsmFitOptions,
) -> Option<f64> {
    refit(experiments, &PmsmFitOptions { start: None, skip_setup_checks: true, ..other }).map(|f| f.fit.loss)
}

/// Which voltage hold the fit assumes.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HoldChoice {
    /// Fit both holds and keep the one with the lower loss.
    #[default]
    Auto,
    /// Voltage held constant in dq (e.g. gym-electric-motor).
    Dq,
    /// Voltage held constant in the stator frame (a real inverter; motulator).
    Stator,
}

impl From<crate::pmsm::model::interval::VoltageHold> for HoldChoice {
    /// The choice that fixes a fit's hold (for a refit at the hold a fit found).
    fn from(hold: crate::pmsm::model::interval::VoltageHold) -> Self {
        match hold {
            crate::pmsm::model::interval::VoltageHold::Dq => Self::Dq,
            crate::pmsm::model::interval::VoltageHold::Stator => Self::Stator,
        }
    }
}

/// Which equations a fit takes: the dynamic model (the exact sampled-data step), the
/// steady-state equations of slow logs ([`crate::pmsm::steady_state`]), or chosen from the
/// logs' sample time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Dynamics {
    /// The dynamic model, unless the sample time is one it cannot resolve (beyond five
    /// electrical time constants, or half an electrical turn per sample) and the log is
    /// not a fast log with its time column in other units: then the steady-state
    /// equations, with a note saying why.
    #[default]
    Auto,
    /// The dynamic model (`--model spm|ipm` with `--force` on a slow log).
    Dynamic,
    /// The steady-state equations (`--model spm-steady|ipm-steady`).
    Steady,
}

/// Options of [`fit_pmsm`](crate::pmsm::fit_pmsm), built with the motor's pole pairs by [`PmsmFitOptions::new`]
/// (there is no default pole-pair number, so none can be forgotten), then changed field by
/// field: `PmsmFitOptions { model: MotorKind::Ipm, ..PmsmFitOptions::new(2) }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PmsmFitOptions {
    /// Pole pairs n_p of the motor (`ω_e = n_p ω_m`); required (0 is an error of
    /// [`fit_pmsm`](crate::pmsm::fit_pmsm)).
    pub pole_pairs: u32,
    /// Surface (`spm`) or interior (`ipm`) magnets.
    #[serde(default)]
    pub model: MotorKind,
    /// Voltage hold.
    #[serde(default)]
    pub hold: HoldChoice,
    /// The voltage that drives the model: the measured terminal voltage (default) or the
    /// controller's reference with its delay and angle advance (stator hold only).
    #[serde(default)]
    pub input: VoltageInput,
    /// Start values in model order (`r_s, l_s, k_e` or `r_s, l_d, l_q, k_e`); `None` =
    /// linear least-squares estimate.
    #[serde(default)]
    pub start: Option<Vec<f64>>,
    /// Parameters held at their start value, by name.
    #[serde(default)]
    pub fixed: Vec<String>,
    /// Parameters held at a given value `(name, value)` \[SI unit of the parameter\],
    /// whatever the start (they need not be listed in `fixed`).
    #[serde(default)]
    pub fixed_values: Vec<(String, f64)>,
    /// Bounds `(name, lower, upper)` replacing the model's defaults. A least-squares start
    /// outside them is clamped into them (with a note); a given start is not.
    #[serde(default)]
    pub bounds: Vec<(String, f64, f64)>,
    /// Known resistance in series with the winding (cable) \[Ω\], subtracted: `r_s` is the
    /// motor's alone, and the report gives the cable apart.
    #[serde(default)]
    pub cable_resistance: f64,
    /// Reference point of the winding and magnet temperatures derived from `r_s` and `psi_f`.
    #[serde(default)]
    pub thermal: Option<ThermalReference>,
    /// The inverter's voltage error as a nuisance input (`v_dt`, estimated or known); for a
    /// fit driven by the reference voltage.
    #[serde(default)]
    pub inverter: Option<InverterModel>,
    /// The switching-resolved PWM inverter between the reference and the motor
    /// ([`PmsmPwm`](crate::pmsm::PmsmPwm)): its `t_d`, `u_th` (and `i_w`) join the
    /// parameters; for a fit driven by the reference voltage, instead of `inverter`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pwm: Option<PwmInverter>,
    /// The modulator's voltage limit \[V\] (`U_dc/√3`): with the reference input, samples
    /// driven by a reference at the limit are weighted out. `None`: not checked.
    #[serde(default)]
    pub voltage_limit: Option<f64>,
    /// Options of the prediction-error fit.
    #[serde(default)]
    pub pem: PemOptions,
    /// Skip the setup checks (a better pole-pair number, a salient log, the speed's unit
    /// and frame): for fits nested in a search, whose final fit runs them.
    #[serde(default)]
    pub skip_setup_checks: bool,
    /// Fit even a log whose sample time the model cannot resolve (h beyond five electrical
    /// time constants of the start, or half an electrical turn per sample), which is
    /// otherwise refused before the fit: such a fit is slow (the exact step's exponential
    /// of a large matrix) and its estimates are not to be trusted (warning `sample_time`).
    #[serde(default)]
    pub force: bool,
    /// Which equations: dynamic, steady state, or chosen from the sample time (default).
    #[serde(default)]
    pub dynamics: Dynamics,
    /// The drive's control (PWM) period h_c \[s\] for the steady-state equations: the
    /// point-sampled currents are then related to the period-mean voltage exactly; `None`:
    /// the continuous equations (their back-EMF reads low by up to `(ω_e h_c)²/12`).
    #[serde(default)]
    pub control_period: Option<f64>,
    /// How the log's current and voltage columns were read (`[currents, voltages]`): an
    /// RMS-scaled column was multiplied by `√2` on reading (MODEL.md §1). The fit works in
    /// peak values whatever they were; the `scaling_assumed` notice offers the estimates
    /// under the convention the data cannot tell from the one read. Default: peak, peak.
    #[serde(default)]
    pub read_scales: [Scale; 2],
    /// The accuracy the fit must reach to be trusted ([`crate::estimate::imprecise`]):
    /// `None` the fit's default (the steady-state equations' [`STEADY_PRECISION`](crate::pmsm::thresholds::STEADY_PRECISION),
    /// none for the dynamic model); `Some(vec![])` none.
    #[serde(default)]
    pub precision: Option<Vec<PrecisionTarget>>,
}

impl PmsmFitOptions {
    /// The defaults for a motor of `pole_pairs` pole pairs n_p: surface magnets, the hold
    /// chosen from the data, the terminal voltage, a least-squares start, every parameter
    /// free within the model's bounds, no cable, inverter or thermal model, the default
    /// prediction-error options, the setup checks on.
    pub fn new(pole_pairs: u32) -> Self {
        Self {
            pole_pairs,
            model: MotorKind::default(),
            hold: HoldChoice::default(),
            input: VoltageInput::default(),
            start: None,
            fixed: Vec::new(),
            fixed_values: Vec::new(),
            bounds: Vec::new(),
            cable_resistance: 0.0,
            thermal: None,
            inverter: None,
            pwm: None,
            voltage_limit: None,
            pem: PemOptions::default(),
            skip_setup_checks: false,
            force: false,
            dynamics: Dynamics::Auto,
            control_period: None,
            read_scales: [Scale::Peak; 2],
            precision: None,
        }
    }
}

/// Applies the fixed flags and bounds of `options` to the model's parameter metadata.
pub(crate) fn configure(params: &mut [Parameter], options: &PmsmFitOptions) -> Result<()> {
    let unknown = |n: &str, what: &str| Error::InvalidOption {
        option: what.into(),
        reason: format!("no parameter `{n}`; the model has {}", params_list(options.model)),
    };
    for name in options.fixed.iter().chain(options.fixed_values.iter().map(|(n, _)| n)) {
        let p = params.iter_mut().find(|p| &p.name == name).ok_or_else(|| unknown(name, "fixed"))?;
        p.fixed = true;
    }
    for (name, lo, hi) in &options.bounds {
        let p = params.iter_mut().find(|p| &p.name == name).ok_or_else(|| unknown(name, "bounds"))?;
        p.lower = *lo;
        p.upper = *hi;
        p.check_bounds()?;
    }
    Ok(())
}

fn params_list(kind: MotorKind) -> String {
    kind.parameter_names().join(", ")
}

/// `options` with the averaged inverter model in place of a switching-resolved one
/// (`--dead-time estimate --dead-time-mask auto`), from the least-squares start, without
/// setup checks: the cheap nested fit that finds a PWM fit's timing
/// (`pmsm::fit::input_search`) and screens its delay check (`pmsm::checks::delay`).
pub(crate) fn averaged_inverter(options: &PmsmFitOptions) -> PmsmFitOptions {
    PmsmFitOptions {
        pwm: None,
        inverter: Some(InverterModel {
            width: None,
            known: None,
            mask: Some(crate::pmsm::model::mask::DeadTimeMask::Auto),
        }),
        start: None,
        skip_setup_checks: true,
        ..options.clone()
    }
}

/// The options of the fits that lead to the final one (the continuation's at smooth leg
/// states, `pmsm::fit::pwm_start::continuation`, and the unmasked fit): `pem` with its
/// relative tolerances `ftol` and `xtol` no tighter than [`STAGE_TOLERANCE`]. Their
/// estimates are only starts (of the next stage, of the loop's search, of the sign mask);
/// the fits on the mask converge at `pem`'s own tolerances, the last on the mask taken
/// again at its own estimate.
pub(crate) fn stage_options(pem: &crate::estimate::PemOptions) -> crate::estimate::PemOptions {
    let mut o = pem.clone();
    o.tolerances.ftol = o.tolerances.ftol.max(STAGE_TOLERANCE);
    o.tolerances.xtol = o.tolerances.xtol.max(STAGE_TOLERANCE);
    o
}

/// The relative tolerance (`ftol`, `xtol`) of the fits that lead to the final one. On the
/// first 1.5 s of the shared 3 µs log (noise-free) the continuation's fits take 9, 9 and 4
/// iterations where they took 17, 27 and 20, and the unmasked fit, whose loss is rough
/// where a predicted current crosses zero at a switching instant, stops after 13 where it
/// crept on to the limit of 200 with its estimate moving by 1e-5; the final estimate moves
/// by less than 0.02 of its standard errors there. On the whole shared IPM log it moves by
/// up to 2.4 of its noise-free standard errors (`l_d` +0.0003 → +0.0008 %): the loss is
/// rough there, and the fit before stopped at another point of it.
pub(crate) const STAGE_TOLERANCE: f64 = 1e-4;
