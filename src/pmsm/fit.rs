//! PMSM fits in one call: least-squares start, voltage-hold selection, prediction-error
//! fit; the result is the generic report wrapped with what only a motor has.
//!
//! This is what the command line runs. The steps (MODEL.md §4–5):
//! 1. start from the linear least-squares estimate (thesis 5.2.1) unless a start is given;
//! 2. fit with the chosen voltage hold; with [`HoldChoice::Auto`] fit both holds (the
//!    second from the first's estimate) and keep the one with the lower loss — the holds
//!    differ at second order in `ω_e h`, which decides between 10⁻⁴ and 10⁻⁷ accuracy;
//! 3. the model derives `K_t = √(3/2) K_e` \[N m/A\] and `ψ_f = √(2/3) K_e / n_p` \[V s\] with
//!    their standard errors (MODEL.md §2).

use super::hold::{DQ_DECISIVE, HoldFits, hold_ambiguity};
use super::interval::{VoltageHold, VoltageInput};
use super::inverter::InverterModel;
use super::kind::MotorKind;
use super::mask::DeadTimeMask;
use super::report::delay_parameter;
pub use super::report::{PmsmFit, StartComparison};
use super::setup::PmsmSetup;
use super::temperature::ThermalReference;
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{CovarianceMethod, FitResult, PemOptions, Timing};
use serde::{Deserialize, Serialize};
use std::time::Instant;

mod beside;
mod holds;
use beside::{Beside, Pending};
use holds::Fitted;

/// Which voltage hold the fit assumes.
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

/// Options of [`fit_pmsm`], built with the motor's pole pairs by [`PmsmFitOptions::new`]
/// (there is no default pole-pair number, so none can be forgotten), then changed field by
/// field: `PmsmFitOptions { model: MotorKind::Ipm, ..PmsmFitOptions::new(2) }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PmsmFitOptions {
    /// Pole pairs n_p of the motor (`ω_e = n_p ω_m`); required (0 is an error of
    /// [`fit_pmsm`]).
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
            voltage_limit: None,
            pem: PemOptions::default(),
            skip_setup_checks: false,
            force: false,
        }
    }
}

/// Fits a PMSM model to one or more logs of one motor (parameters shared unless listed in
/// `options.pem.per_experiment`).
///
/// # Errors
/// [`Error::InvalidPolePairs`] for `options.pole_pairs = 0`; [`Error::MissingChannel`]
/// for a log without `ud, uq, id, iq, w_m`;
/// [`Error::InvalidOption`] for no experiments, a start of the wrong length, an unknown
/// parameter name in `fixed`/`fixed_values`/`bounds`; [`Error::StartOutsideBounds`] for a
/// given start or fixed value outside the bounds;
/// [`Error::Numerical`] when the least-squares start cannot be computed (no excitation)
/// or gives a non-positive `R_s`/`L`; and every error of [`crate::estimate::fit`].
///
/// # Example
/// ```no_run
/// use greybox::pmsm::{fit_pmsm, PmsmFitOptions};
/// # fn main() -> greybox::Result<()> {
/// let log = greybox::pmsm::read_log("data/sample.csv.gz", &Default::default())?;
/// let fit = fit_pmsm(&[log], &PmsmFitOptions::new(4))?;
/// println!("{fit}");
/// println!("K_t = {:.5} N m/A", fit.derived("k_t").unwrap().value);
/// # Ok(()) }
/// ```
pub fn fit_pmsm(experiments: &[Experiment], options: &PmsmFitOptions) -> Result<PmsmFit> {
    let t0 = Instant::now();
    let n_p = options.pole_pairs;
    super::interval::check_pole_pairs(n_p)?;
    if experiments.is_empty() {
        return Err(Error::InvalidOption { option: "experiments".into(), reason: "no log given".into() });
    }
    if options.inverter.and_then(|i| i.mask) == Some(DeadTimeMask::Auto) {
        return super::mask::fit_auto_mask(experiments, options);
    }
    let mut names: Vec<&str> = options.model.parameter_names().to_vec();
    if options.inverter.is_some() {
        names.push("v_dt");
    }
    // The checks that need no estimate run on a thread of their own from the start, beside
    // the start, the fits and their statistics (which leave a core idle at times): the
    // setup scan (one regression Gram; a log the scan cannot read is not checked) and the
    // dead-time check. On the calling thread when the caller's rayon pool has one thread.
    let beside = || Beside {
        scan: (!options.skip_setup_checks)
            .then(|| super::detect::scan_gram(experiments, options.input).ok())
            .flatten(),
        dead: {
            let (kind, input, inverter) = (options.model, options.input, options.inverter.is_some());
            let n_theta = kind.parameter_names().len();
            super::checks::dead_time_advice(experiments, n_p, kind, input, n_theta, inverter)
        },
    };
    if rayon::current_num_threads() == 1 {
        return fit_beside(experiments, options, t0, &names, Pending::Ready(beside()));
    }
    std::thread::scope(|scope| {
        fit_beside(experiments, options, t0, &names, Pending::Thread(scope.spawn(beside)))
    })
}

/// [`fit_pmsm`] once the checks beside it are under way.
fn fit_beside(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    t0: Instant,
    names: &[&str],
    beside: Pending<'_, Beside>,
) -> Result<PmsmFit> {
    let n_p = options.pole_pairs;
    let fitted = holds::fit_from_start(experiments, options, names);
    let Beside { scan, dead } = beside.get();
    // A salient log fitted without the saliency is an error before any other: the start's,
    // the options', the fits'.
    let structure = match &scan {
        Some(g) if options.inverter.is_none() => super::detect::check_structure(g, n_p, options.model)?,
        _ => None,
    };
    let Fitted { fits, mut notes, ls_theta, modulator } = match (fitted, &scan) {
        (Err(Error::Numerical { context, reason }), Some(g)) if context == "least-squares start" => {
            let named = super::columns::start_failure(g, experiments, n_p, options.model, options.input);
            return Err(Error::Numerical {
                context,
                reason: match named {
                    Some(why) => format!("{reason}. Likely cause: {why}"),
                    None => reason,
                },
            });
        }
        (fitted, _) => fitted?,
    };
    let HoldFits { best: (hold, best), others, losses, notes: hold_notes } = fits;
    notes.extend(hold_notes);
    let pmsm_advice: Vec<String> = hold_ambiguity(&best, hold, &others, names).into_iter().collect();
    // The regression sees the whole series resistance.
    let motor: Vec<f64> = options
        .model
        .parameter_names()
        .iter()
        .filter_map(|n| {
            best.parameter(n).map(|p| p.value + if *n == "r_s" { options.cable_resistance } else { 0.0 })
        })
        .collect();
    // The late-voltage check and the setup checks' own warnings need the estimate: side by side.
    let (late, setup_warnings) = rayon::join(
        || super::checks::late_voltage_advice(experiments, n_p, options.model, options.input, &motor),
        || (!options.skip_setup_checks).then(|| super::detect::warnings(experiments, n_p, &best)),
    );
    let model_checks = super::checks::merge(dead, late);
    if losses.len() > 1 {
        let why = match (hold, modulator) {
            (VoltageHold::Stator, true) => format!(
                "the stator hold: the log carries a modulator's reference, and a modulator holds its output in \
                 the stator frame; the dq hold's loss is not {DQ_DECISIVE} times lower"
            ),
            (VoltageHold::Dq, true) => format!(
                "the dq hold, whose loss is more than {DQ_DECISIVE} times lower than the stator hold's although the \
                 log carries a modulator's reference"
            ),
            (h, false) => format!("the {h} hold by the lower loss (no modulator reference in the log)"),
        };
        notes.push(format!(
            "voltage hold chosen automatically: {why} (losses {})",
            losses.iter().map(|(h, l, _)| format!("{h} {l:.6e}")).collect::<Vec<_>>().join(", ")
        ));
    }
    let start_comparison = match ls_theta {
        None => Vec::new(),
        Some(ls) => names
            .iter()
            .zip(&ls)
            .filter_map(|(n, &l)| {
                let p = best.parameter(n)?;
                (!p.fixed).then(|| StartComparison {
                    name: n.to_string(),
                    least_squares: l,
                    pem: p.value,
                    difference_percent: 100.0 * (l - p.value) / p.value,
                })
            })
            .collect(),
    };
    let fit_s = t0.elapsed().as_secs_f64();
    let parameters = best.parameters.iter().cloned().chain(delay_parameter(options.input, None)).collect();
    let mut warnings = best.warnings.clone();
    warnings.extend(model_checks);
    if !options.skip_setup_checks {
        warnings.extend(structure);
        if let Some(g) = &scan {
            warnings.extend(super::detect::pole_pair_warning(g, experiments, options, best.fit.loss));
            warnings.extend(super::columns::warning(g, experiments, options, best.fit.loss));
        }
    }
    warnings.extend(setup_warnings.into_iter().flatten());
    let plain = options.model == MotorKind::Spm
        && options.input == VoltageInput::Terminal
        && options.inverter.is_none();
    if plain && best.uncertainty.method == CovarianceMethod::BatchMeans {
        // `motor` holds the whole series resistance already: no cable on top.
        let setup = PmsmSetup::new(n_p, hold);
        warnings.extend(super::noise::input_noise_notice(experiments, setup, &motor));
    }
    Ok(PmsmFit {
        report: FitResult {
            timing: Timing { fit_s, total_s: fit_s, ..best.timing.clone() },
            parameters,
            warnings,
            ..best
        },
        pole_pairs: n_p,
        hold,
        input: options.input,
        cable_resistance: options.cable_resistance,
        inverter: options.inverter,
        hold_losses: losses.iter().map(|(h, l, _)| (*h, *l)).collect(),
        start_comparison,
        pmsm_advice,
        pmsm_notes: notes,
    })
}
