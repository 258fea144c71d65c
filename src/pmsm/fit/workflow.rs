//! The whole PMSM workflow in one call, [`fit_pmsm`]: the options checked, then the fit
//! ([`super::base`]) or, with [`DeadTimeMask::Auto`], the fixed-point iteration of masked
//! fits ([`super::auto_mask`]). It sits above both and gives them itself as the refit that
//! confirms a suspected setup mistake, so that nothing below calls back up. A fit from the
//! reference voltage or with the inverter model is then refitted on the logs' consecutive
//! parts, whose disagreement makes it untrusted (`checks::segments`), and a masked one with
//! more current noise, whose shift shows the noise's bias (`checks::noise_bias`).

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::imprecise;
use crate::pmsm::checks::sampling::Sampling;
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::log::DqLogs;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::mask::DeadTimeMask;
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::options::{Dynamics, PmsmFitOptions};

/// Fits a PMSM model to one or more logs of one motor (parameters shared unless listed in
/// `options.pem.per_experiment`).
///
/// # Errors
/// [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError::InvalidPolePairs) for `options.pole_pairs = 0`; [`Error::MissingChannel`]
/// for a log without `ud, uq, id, iq, w_m`;
/// [`Error::InvalidOption`] for no experiments, a control period not positive, a start of the wrong length, an unknown
/// parameter name in `fixed`/`fixed_values`/`bounds`/`precision`; [`Error::StartOutsideBounds`] for a
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
    check(experiments, options)?;
    // Every log validated once here and passed down.
    fit_dq(&DqLogs::try_new(experiments)?, options)
}

/// The options and logs [`fit_pmsm`] refuses before it reads a log's channels.
///
/// # Errors
/// As [`fit_pmsm`]: the pole pairs, no log, a control period not positive, a stated
/// accuracy for a parameter the model does not have.
fn check(experiments: &[Experiment], options: &PmsmFitOptions) -> Result<()> {
    crate::pmsm::log::signals::check_pole_pairs(options.pole_pairs)?;
    if experiments.is_empty() {
        return Err(Error::InvalidOption { option: "experiments".into(), reason: "no log given".into() });
    }
    // Checked here, not only by the steady-state fit: a dynamic fit would ignore a bad one.
    if let Some(h) = options.control_period.filter(|h| !(h.is_finite() && *h > 0.0)) {
        return Err(Error::InvalidOption {
            option: "control_period".into(),
            reason: format!("{h} s is not a positive sample time (the drive's control period)"),
        });
    }
    // A target's name is checked here: one the report does not hold would switch it off.
    let names = options.model.parameter_names();
    if let Some(t) = options.precision.iter().flatten().find(|t| !names.contains(&t.parameter.as_str())) {
        return Err(Error::InvalidOption {
            option: "precision".into(),
            reason: format!(
                "no parameter `{}` to state an accuracy for; the model has {}",
                t.parameter,
                names.join(", ")
            ),
        });
    }
    Ok(())
}

/// [`fit_pmsm`] of logs validated once where the fit starts ([`DqLogs`]): a caller that
/// fits the same logs several times (the input's search) validates them once.
///
/// # Errors
/// As [`fit_pmsm`].
pub(crate) fn fit_dq(dq: &DqLogs<'_>, options: &PmsmFitOptions) -> Result<PmsmFit> {
    let experiments = dq.experiments();
    check(experiments, options)?;
    if let Some(why) = super::steady::chosen_up_front(dq, options) {
        return super::steady::fit(dq, options, why);
    }
    let refit = |e: &[Experiment], o: &PmsmFitOptions| fit_pmsm(e, o).ok().map(|f| f.report);
    let fit = if options.inverter.and_then(|i| i.mask) == Some(DeadTimeMask::Auto) {
        super::auto_mask::fit(dq, options, &refit)?
    } else {
        match super::base::fit(dq, options, &refit) {
            // A sample time the dynamic model cannot resolve: the steady-state equations,
            // unless they were ruled out (`--force`, nested fits, the dynamic model asked for).
            Err(Error::Numerical { context, reason })
                if context == super::steady::SAMPLE_TIME
                    && options.dynamics == Dynamics::Auto
                    && !options.skip_setup_checks =>
            {
                return super::steady::fit_if_slow(dq, options).ok_or(Error::Numerical { context, reason });
            }
            other => other?,
        }
    };
    if options.skip_setup_checks {
        return Ok(fit);
    }
    let parts = part_options(options, &fit);
    // The measured terminal voltage is the model's input as logged, with its noise; the
    // reference voltage and the inverter are modelled, and their model's error is what the
    // parts show.
    if options.inverter.is_none() && options.input == VoltageInput::Terminal {
        let fit = match point_sampled(experiments, options, &fit, &refit) {
            None => match super::steady_agreement::warning(experiments, options, &fit.report) {
                Some(w) => with_warnings(fit, [w]),
                None => fit,
            },
            // The steady-state equations take the samples as points: chosen when the choice is
            // automatic, as for a log too slow for the dynamic model.
            Some(Sampling::Points(why)) if options.dynamics == Dynamics::Auto && !options.force => {
                match super::steady::fit(dq, options, Some(why.clone())) {
                    Ok(steady) => return Ok(steady),
                    Err(e) => with_warnings(fit, [point_sampled_warning(&why, Some(&e))]),
                }
            }
            Some(Sampling::Points(why)) => with_warnings(fit, [point_sampled_warning(&why, None)]),
            Some(Sampling::Unclear(why)) => with_warnings(fit, [point_sampled_unclear(&why)]),
        };
        let bias = crate::pmsm::checks::voltage_bias::warning(
            dq,
            options,
            &fit.report,
            PmsmSetup::new(fit.pole_pairs, fit.hold),
            &parts,
            &refit,
        );
        return Ok(judged(fit, options, bias));
    }
    let masked = fit.inverter.and_then(|i| i.mask).is_some();
    let (segments, noise) = rayon::join(
        || crate::pmsm::checks::segments::warning(experiments, &parts, &refit),
        || {
            masked
                .then(|| crate::pmsm::checks::noise_bias::warning(experiments, &parts, &fit.report, &refit))
                .flatten()
        },
    );
    Ok(judged(fit, options, segments.into_iter().chain(noise)))
}

/// What makes a dynamic fit more precise, the `imprecise` warning's advice.
pub(super) const PRECISION_ADVICE: &str = "the log does not carry that much information; log longer, or excite what the \
                                           advice names (speed, current, i_d); --precision sets the targets (off: none)";

/// `fit` with `warnings` added after its report's.
fn with_warnings(fit: PmsmFit, warnings: impl IntoIterator<Item = crate::estimate::Warning>) -> PmsmFit {
    let warnings = fit.report.warnings.iter().cloned().chain(warnings).collect();
    PmsmFit { report: crate::estimate::FitResult { warnings, ..fit.report }, ..fit }
}

/// The dynamic fit `fit` with its checks' `warnings` and the `imprecise` warning of the
/// accuracy `options` state (`--precision`; a dynamic fit states none by default, the
/// steady-state fit judges its own): `fit` itself when there is none to add.
fn judged(
    fit: PmsmFit,
    options: &PmsmFitOptions,
    warnings: impl IntoIterator<Item = crate::estimate::Warning>,
) -> PmsmFit {
    let precise = options.precision.as_ref().and_then(|t| {
        imprecise(&fit.report.parameters, fit.report.uncertainty.dof, t, "--precision", PRECISION_ADVICE)
    });
    let mut added = warnings.into_iter().chain(precise).peekable();
    match added.peek() {
        None => fit,
        Some(_) => with_warnings(fit, added),
    }
}

/// The voltage-sampling check of a dynamic fit `fit` from the terminal voltage
/// ([`crate::pmsm::checks::sampling::point_sampled`]) at its pole pairs, hold and cable.
fn point_sampled(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    fit: &PmsmFit,
    refit: crate::pmsm::options::RefitReport<'_>,
) -> Option<Sampling> {
    let setup =
        PmsmSetup { cable_resistance: options.cable_resistance, ..PmsmSetup::new(fit.pole_pairs, fit.hold) };
    crate::pmsm::checks::sampling::point_sampled(experiments, options, &fit.report, setup, refit)
}

/// The untrusted `point_sampled_voltage` warning saying `why`, and why the steady-state
/// equations were not fitted instead (`steady`'s error, or the dynamic model asked for).
fn point_sampled_warning(why: &str, steady: Option<&Error>) -> crate::estimate::Warning {
    let instead = match steady {
        Some(e) => format!("the steady-state equations, which take the samples as points, could not be fitted ({e})"),
        None => "the dynamic model was asked for (--force); the steady-state equations take the samples as points \
                 (--model spm-steady or ipm-steady)"
            .into(),
    };
    crate::estimate::Warning::untrusted(
        "point_sampled_voltage",
        format!("{why}, so the estimates carry the model's error; {instead}"),
    )
}

/// The untrusted `point_sampled_voltage` warning of a voltage that may be point samples
/// (`why`): the fit stays the dynamic one, untrusted.
fn point_sampled_unclear(why: &str) -> crate::estimate::Warning {
    crate::estimate::Warning::untrusted(
        "point_sampled_voltage",
        format!(
            "{why}; the dynamic model's estimates may then carry the held voltage's error: compare with the \
             steady-state equations, which take the samples as points (--model spm-steady or ipm-steady)"
        ),
    )
}

/// The options of the segment check's fits of parts of the logs: the fit's own hold, input
/// and inverter model (the automatic mask's last threshold; the PWM inverter's loop, leg
/// state and nuisance parameters found by the fit), started from its estimate, without
/// setup checks of their own.
fn part_options(options: &PmsmFitOptions, fit: &PmsmFit) -> PmsmFitOptions {
    PmsmFitOptions {
        start: fit.inverter_start(options.model),
        hold: fit.hold.into(),
        input: fit.input,
        inverter: fit.inverter,
        // The controller's loop is the drive's: the parts keep the whole log's, and its leg
        // state (the carrier's first edge is each part's own).
        pwm: options.pwm.zip(fit.pwm).map(|(p, f)| crate::pmsm::model::pwm::PwmInverter {
            search_speed_pll: false,
            i_w: f.i_w,
            estimate_i_w: f.estimate_i_w,
            ..p
        }),
        // The inverter is the same hardware along the log: its nuisance parameters held at
        // the whole fit's estimate, the parts test the motor's. Under current noise a part
        // cannot tell the dead time's timing from the threshold's constant drop (0.05 A put
        // t_d at 0 and u_th at the whole V_dt in two of four parts, and r_s, l_s 5 % off).
        fixed: options
            .fixed
            .iter()
            .cloned()
            .chain(fit.pwm.iter().flat_map(|_| ["t_d", "u_th"].map(String::from)))
            .collect(),
        skip_setup_checks: true,
        ..options.clone()
    }
}
