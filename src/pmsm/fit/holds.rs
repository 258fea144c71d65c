//! The fits of [`crate::pmsm::fit_pmsm`] from their start: the least-squares start unless one is
//! given, the user's constraints on it, the holds to fit, the weighting (voltage limit,
//! dead-time mask) and the fits of those holds (MODEL.md §4–5).

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{CLOSE_START_DAMPING, Weighting};
use crate::pmsm::checks::limit::{VoltageLimitWeighting, delay_of};
use crate::pmsm::fit::hold::{HoldFits, fit_holds_of};
use crate::pmsm::linear::start::least_squares_start;
use crate::pmsm::log::DqLogs;
use crate::pmsm::model::interval::{VoltageHold, VoltageInput};
use crate::pmsm::model::inverter::masked_pem;
use crate::pmsm::model::ipm::PmsmIpm;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::mask::{DeadTimeMask, DeadTimeMaskWeighting};
use crate::pmsm::model::pwm::{PmsmPwm, PwmInverter};
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::model::spm::PmsmSpm;
use crate::pmsm::options::configure;
use crate::pmsm::options::{HoldChoice, PmsmFitOptions};
use crate::report::eng::format_eng;

/// What [`fit_from_start`] gives the rest of [`crate::pmsm::fit_pmsm`].
pub(super) struct Fitted {
    /// The fits of the holds tried, the best first.
    pub fits: HoldFits,
    /// Notes on the start, the holds and the weighting, in order.
    pub notes: Vec<String>,
    /// The least-squares start (model order, `v_dt` included when estimated), when used.
    pub ls_theta: Option<Vec<f64>>,
    /// Whether every log carries a modulator's reference `ud_ref, uq_ref`.
    pub modulator: bool,
    /// The PWM inverter fitted through, its first carrier edge resolved.
    pub pwm: Option<crate::pmsm::model::pwm::PwmInverter>,
    /// The voltage input of the fits: the options', or with the controller's loop found.
    pub input: VoltageInput,
    /// Warnings of the PWM fit's stages (the controller's loop not pinned by the log).
    pub warnings: Vec<crate::estimate::Warning>,
}

/// The start of the fits of the logs `dq` under `options` (fitted parameters `names`, model
/// order) and the fits of the holds `options.hold` allows.
///
/// # Errors
/// Those of [`crate::pmsm::fit_pmsm`] but the setup checks': a start of the wrong length, the
/// least-squares start's, the user's constraints', the hold or voltage-limit options', and
/// the fits'.
pub(super) fn fit_from_start(dq: &DqLogs<'_>, options: &PmsmFitOptions, names: &[&str]) -> Result<Fitted> {
    let experiments = dq.experiments();
    let n_p = options.pole_pairs;
    // The start of v_dt when the start comes from elsewhere: the known value, or 0.
    let v_dt0 = options.inverter.map(|i| i.known.unwrap_or(0.0));
    let mut notes = Vec::new();
    let mut ls_theta = None;
    let start = match (&options.start, &options.pwm) {
        (None, Some(pwm)) => {
            let (s, note) = super::pwm_start::start(dq, options, pwm)?;
            notes.push(note);
            s
        }
        (Some(s), _) => {
            let s: Vec<f64> = match v_dt0 {
                Some(v) if s.len() + 1 == names.len() => s.iter().copied().chain([v]).collect(),
                _ => s.clone(),
            };
            if s.len() != names.len() {
                return Err(Error::InvalidOption {
                    option: "start".into(),
                    reason: format!(
                        "{} values given, the {} model has {} ({})",
                        s.len(),
                        options.model.model_name(),
                        names.len(),
                        names.join(", ")
                    ),
                });
            }
            notes.push("start given by the user".to_string());
            s
        }
        (None, None) => {
            let (ls_names, theta) = least_squares_start(
                dq.views(),
                n_p,
                options.model,
                options.input,
                options.cable_resistance,
                options.inverter.as_ref(),
            )?;
            notes.push(format!(
                "start from linear least squares: {}",
                ls_names
                    .iter()
                    .zip(&theta)
                    .map(|(n, v)| format!("{n} = {}", format_eng(*v, unit_of(options.model, n), 7)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            let with_v_dt = ls_names.len() == names.len();
            ls_theta = Some(theta.clone());
            theta.into_iter().chain(v_dt0.filter(|_| !with_v_dt)).collect()
        }
    };
    let start = crate::pmsm::linear::start::user_start(start, names, options, &mut notes)?;
    // A sample time the model cannot resolve at the start's R and L: refused before a fit
    // that would be slow and wrong.
    let value = |wanted: &[&str]| {
        names
            .iter()
            .zip(&start)
            .filter(|(n, _)| wanted.contains(n))
            .map(|(_, v)| *v)
            .fold(f64::INFINITY, f64::min)
    };
    let (r_s, l) = (value(&["r_s"]), value(&["l_s", "l_d", "l_q"]));
    if !options.skip_setup_checks
        && !options.force
        && let Some(why) = crate::pmsm::checks::detect::sample_time_problem(dq.views(), n_p, r_s, l)
    {
        return Err(Error::Numerical {
            context: super::steady::SAMPLE_TIME.into(),
            reason: format!(
                "{why}. Refused before the fit, which would be slow and wrong; --force fits it anyway"
            ),
        });
    }
    let reference = options.input != VoltageInput::Terminal;
    let holds: &[VoltageHold] = match options.hold {
        HoldChoice::Dq if reference => {
            return Err(Error::InvalidOption {
                option: "hold".into(),
                reason: "a reference voltage is applied by a modulator, which holds it in the stator frame"
                    .into(),
            });
        }
        HoldChoice::Dq => &[VoltageHold::Dq],
        HoldChoice::Stator => &[VoltageHold::Stator],
        HoldChoice::Auto if reference => {
            notes.push("reference voltage: the modulator holds it in the stator frame (stator hold)".into());
            &[VoltageHold::Stator]
        }
        HoldChoice::Auto => &[VoltageHold::Stator, VoltageHold::Dq],
    };
    if let Some(l) = options.voltage_limit.filter(|l| !(l.is_finite() && *l > 0.0)) {
        return Err(Error::InvalidOption {
            option: "voltage_limit".into(),
            reason: format!("{l} V must be positive and finite (U_dc/√3)"),
        });
    }
    let inner = options.pem.weighting.rule()?;
    let limited = options
        .voltage_limit
        .filter(|_| options.input != VoltageInput::Terminal)
        .map(|limit| VoltageLimitWeighting { inner: inner.as_ref(), limit, delay: delay_of(options.input) });
    let weighting: &dyn Weighting = match &limited {
        Some(l) => l,
        None => inner.as_ref(),
    };
    if let Some(l) = &limited {
        let n: usize = experiments.iter().map(|e| l.count(e)).sum();
        notes.push(format!(
            "{n} samples driven by a reference at the voltage limit {:.1} V weighted out",
            l.limit
        ));
    }
    let masked = match options.inverter.and_then(|i| i.mask) {
        Some(DeadTimeMask::Current(threshold)) => {
            Some(DeadTimeMaskWeighting { inner: weighting, n_p, threshold })
        }
        _ => None,
    };
    let weighting: &dyn Weighting = match &masked {
        Some(m) => m,
        None => weighting,
    };
    if let Some(m) = &masked {
        let n: usize = experiments.iter().map(|e| m.count(e)).sum();
        let total: usize = experiments.iter().map(Experiment::len).sum();
        notes.push(format!(
            "dead-time mask: {n} of {total} samples weighted out (a phase current within {:.4} A of zero)",
            m.threshold
        ));
    }
    let skip = options.pwm.map(|_| super::pwm_start::SkipStart {
        inner: weighting,
        skip: super::pwm_start::skipped(options.input),
    });
    let weighting: &dyn Weighting = match &skip {
        Some(s) => s,
        None => weighting,
    };
    let (mut pem, pem_note) = masked_pem(options.inverter.as_ref(), &options.pem);
    notes.extend(pem_note);
    if ls_theta.is_some() {
        // The linear least-squares start is close: nearly Gauss-Newton steps from it.
        pem.initial_damping = pem.initial_damping.or(Some(CLOSE_START_DAMPING));
    }
    let modulator = crate::pmsm::log::modulator_reference(dq.views());
    let setup = |hold: VoltageHold| PmsmSetup {
        n_p,
        hold,
        input: options.input,
        cable_resistance: options.cable_resistance,
        thermal: options.thermal,
        inverter: options.inverter,
    };
    macro_rules! fit_holds {
        ($model:path) => {
            fit_holds_of(
                holds,
                &start,
                names,
                modulator,
                |h| {
                    let mut m = <$model>::from_setup(setup(h));
                    configure(m.parameters_mut(), options)?;
                    Ok(m)
                },
                experiments,
                &pem,
                weighting,
            )
        };
    }
    let pwm = match options.pwm {
        Some(pwm) => {
            let (pwm, note) = super::pwm_start::resolve_edge(
                experiments,
                setup(VoltageHold::Stator),
                options,
                pwm,
                &start,
            )?;
            notes.extend(note);
            Some(pwm)
        }
        None => None,
    };
    let mut input = options.input;
    let mut fitted_pwm = pwm;
    let mut warnings = Vec::new();
    let fits = match (pwm, options.model) {
        (Some(pwm), kind) => {
            // The PWM model of an inverter and input at a hold, as the options configure it.
            let model_at = |h: VoltageHold, pwm: PwmInverter, input: VoltageInput| -> Result<PmsmPwm> {
                let mut m = PmsmPwm::new(PmsmSetup { input, ..setup(h) }, kind, pwm);
                configure(m.parameters_mut(), options)?;
                Ok(m)
            };
            let stage_pem = crate::pmsm::options::stage_options(&pem);
            // A fit at the tolerances of `pem`: the final fits' and the stages'.
            macro_rules! fit_at {
                ($pem:expr) => {
                    |experiments: &[Experiment],
                     pwm: PwmInverter,
                     input: VoltageInput,
                     start: &[f64],
                     names: &[&str],
                     weighting: &dyn Weighting,
                     held: &[&str]| {
                        fit_holds_of(
                            holds,
                            start,
                            names,
                            modulator,
                            |h| {
                                let mut m = model_at(h, pwm, input)?;
                                for p in
                                    m.parameters_mut().iter_mut().filter(|p| held.contains(&p.name.as_str()))
                                {
                                    p.fixed = true;
                                }
                                Ok(m)
                            },
                            experiments,
                            $pem,
                            weighting,
                        )
                    }
                };
            }
            let fit = fit_at!(&pem);
            let stage_fit = fit_at!(&stage_pem);
            let model = |pwm: PwmInverter, input: VoltageInput| model_at(VoltageHold::Stator, pwm, input);
            let (fits, chosen, inverter) = super::pwm_fit::stages(
                !options.skip_setup_checks,
                dq,
                &pwm,
                options.input,
                &start,
                names,
                weighting,
                &model,
                &fit,
                &stage_fit,
                &mut notes,
                &mut warnings,
            )?;
            input = chosen;
            fitted_pwm = Some(inverter);
            Ok(fits)
        }
        (None, MotorKind::Spm) => fit_holds!(PmsmSpm),
        (None, MotorKind::Ipm) => fit_holds!(PmsmIpm),
    }?;
    Ok(Fitted { fits, notes, ls_theta, modulator, pwm: fitted_pwm, input, warnings })
}

/// The unit of parameter `name` of `kind`, `V` for the dead-time voltage `v_dt`.
fn unit_of(kind: MotorKind, name: &str) -> &'static str {
    kind.table().iter().find(|p| p.name == name).map_or("V", |p| p.unit)
}
