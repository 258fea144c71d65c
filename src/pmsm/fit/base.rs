//! One PMSM fit under [`crate::pmsm::fit_pmsm`] (which calls it once, or per step of the
//! automatic dead-time mask): least-squares start, voltage-hold selection, prediction-error
//! fit, the checks beside and after it; the result is the generic report wrapped with what
//! only a motor has. The steps (MODEL.md §4–5):
//! 1. start from the linear least-squares estimate (thesis 5.2.1) unless a start is given;
//! 2. fit with the chosen voltage hold; with [`HoldChoice::Auto`](crate::pmsm::HoldChoice::Auto) fit both holds (the
//!    second from the first's estimate) and keep the one with the lower loss — the holds
//!    differ at second order in `ω_e h`, which decides between 10⁻⁴ and 10⁻⁷ accuracy;
//! 3. the model derives `K_t = √(3/2) K_e` \[N m/A\] and `ψ_f = √(2/3) K_e / n_p` \[V s\] with
//!    their standard errors (MODEL.md §2).

use crate::error::{Error, Result};
use crate::estimate::{CovarianceMethod, FitResult, Timing};
use crate::pmsm::fit::hold::{DQ_DECISIVE, GIVE_THE_HOLD, HOLD_TIE_Z, HoldFits, hold_ambiguity};
use crate::pmsm::fit::report::delay_parameter;
use crate::pmsm::fit::report::{PmsmFit, StartComparison};
use crate::pmsm::log::DqLogs;
use crate::pmsm::model::interval::{VoltageHold, VoltageInput};
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::options::{PmsmFitOptions, RefitReport};
use std::time::Instant;

use super::beside::{Beside, Pending};
use super::holds::{self, Fitted};

/// [`crate::pmsm::fit_pmsm`] once its options are checked, without a dead-time mask to find
/// (the workflow and the automatic mask call it): the start, the holds' fits, the checks
/// beside and after them, and the report. `refit` fits other logs or options for the checks
/// that confirm a setup mistake.
///
/// # Errors
/// Those of [`crate::pmsm::fit_pmsm`].
pub(super) fn fit(dq: &DqLogs<'_>, options: &PmsmFitOptions, refit: RefitReport<'_>) -> Result<PmsmFit> {
    let t0 = Instant::now();
    let mut names: Vec<&str> = options.model.parameter_names().to_vec();
    if options.inverter.is_some() {
        names.push("v_dt");
    }
    if let Some(pwm) = &options.pwm {
        names.extend(pwm.parameter_names());
    }
    // The checks that need no estimate run on a thread of their own from the start, beside
    // the start, the fits and their statistics (which leave a core idle at times): the
    // setup scan (one regression Gram; a log the scan cannot read is not checked), the logs
    // prepared for the checks on the voltage equations and a PWM fit's delay screen (three
    // averaged fits). On the calling thread when the caller's rayon pool has one thread.
    let beside = || {
        let logs = crate::pmsm::checks::prepared::prepare(dq.views(), options);
        Beside {
            scan: (!options.skip_setup_checks)
                .then(|| crate::pmsm::checks::columns::scan(dq.views(), options.input).ok())
                .flatten(),
            logs,
            delay_screen: crate::pmsm::checks::delay::screen(dq.experiments(), options, refit),
        }
    };
    if rayon::current_num_threads() == 1 {
        return fit_beside(dq, options, refit, t0, &names, Pending::Ready(beside()));
    }
    std::thread::scope(|scope| {
        fit_beside(dq, options, refit, t0, &names, Pending::Thread(scope.spawn(beside)))
    })
}

/// [`fit`] once the checks beside it are under way.
fn fit_beside(
    dq: &DqLogs<'_>,
    options: &PmsmFitOptions,
    refit: RefitReport<'_>,
    t0: Instant,
    names: &[&str],
    beside: Pending<'_, Beside<'_>>,
) -> Result<PmsmFit> {
    let n_p = options.pole_pairs;
    let experiments = dq.experiments();
    let fitted = holds::fit_from_start(dq, options, names);
    let Beside { scan, logs, delay_screen } = beside.get();
    // A salient log fitted without the saliency is an error before any other: the start's,
    // the options', the fits'.
    let structure = match &scan {
        Some(g) if options.inverter.is_none() && options.pwm.is_none() => {
            crate::pmsm::checks::detect::check_structure(&g.gram, n_p, options.model)?
        }
        _ => None,
    };
    let Fitted { fits, mut notes, ls_theta, modulator, pwm, input, warnings: stage_warnings } =
        match (fitted, &scan) {
            (Err(Error::Numerical { context, reason }), Some(g)) if context == "least-squares start" => {
                let named = crate::pmsm::checks::columns::start_failure(g, dq.views(), options);
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
    let HoldFits { best: (hold, best), others, losses, notes: hold_notes, tied } = fits;
    notes.extend(hold_notes);
    let pmsm_advice: Vec<String> = hold_ambiguity(&best, hold, &others, names).into_iter().collect();
    // The regression sees the whole series resistance.
    // (A fit without one of them leaves the regression's checks nothing to compare.)
    let motor = options.series_theta(&best).unwrap_or_default();
    // The late-voltage check, the dead-time check where it can speak (it reads the fit's
    // residuals) and the setup checks' own warnings: side by side.
    let ((late, dead), setup_warnings) = rayon::join(
        || {
            let v_dt = best.parameter("v_dt").map(|p| p.value);
            rayon::join(
                || crate::pmsm::checks::advice::late_voltage_advice(&logs, options, &motor, v_dt),
                || crate::pmsm::checks::advice::dead_time_advice(&logs, options, &best),
            )
        },
        || {
            (!options.skip_setup_checks)
                .then(|| crate::pmsm::checks::detect::warnings(dq.views(), n_p, &best, options.read_scales))
        },
    );
    let (late, suspect) = late;
    // A late voltage the residual check suspects on every log but cannot name (current
    // noise hides its correlation): the refit with the voltage as a reference decides.
    let late_refit =
        suspect.then(|| super::late_voltage::warning(experiments, options, &best, refit)).flatten();
    let model_checks = crate::pmsm::checks::advice::merge(dead, late);
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
            (h, false) => match tied {
                Some(z) => format!(
                    "the {h} hold: the holds' losses differ by no more than the residuals' noise explains ({z:.1} \
                     of its standard deviations, below {HOLD_TIE_Z}), and an inverter holds its output in the stator \
                     frame (no modulator reference in the log)"
                ),
                None => format!("the {h} hold by the lower loss (no modulator reference in the log)"),
            },
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
    warnings.extend(late_refit);
    if !options.skip_setup_checks {
        warnings.extend(structure);
        if let Some(g) = &scan {
            warnings.extend(crate::pmsm::checks::pole_pairs::pole_pair_warning(
                &g.gram,
                experiments,
                options,
                best.fit.loss,
                &|alt| super::hold::noise_z_against(&best, alt),
                refit,
            ));
            warnings.extend(super::current_offset::warning(
                &g.gram,
                experiments,
                options,
                &best,
                hold,
                refit,
            ));
            warnings.extend(super::angle_offset::warning(&g.gram, experiments, options, &best, hold, refit));
            warnings.extend(crate::pmsm::checks::columns::warning(
                g,
                experiments,
                options,
                best.fit.loss,
                refit,
            ));
        }
        warnings.extend(crate::pmsm::checks::delay::warning(
            experiments,
            options,
            best.fit.loss,
            refit,
            delay_screen,
        ));
    }
    warnings.extend(setup_warnings.into_iter().flatten());
    warnings.extend(stage_warnings);
    // Holds the noise ties whose estimates differ: the log cannot say which is right.
    if let (Some(z), Some(advice)) = (tied, pmsm_advice.first()) {
        warnings.push(crate::estimate::Warning::untrusted(
            "hold_ambiguous",
            format!(
                "{advice}; their losses differ by {z:.1} standard deviations of the residuals' noise, so the \
                 data cannot choose: {GIVE_THE_HOLD}"
            ),
        ));
    }
    let plain = options.model == MotorKind::Spm
        && options.input == VoltageInput::Terminal
        && options.inverter.is_none();
    if plain && best.uncertainty.method == CovarianceMethod::BatchMeans {
        // `motor` holds the whole series resistance already: no cable on top.
        let setup = PmsmSetup::new(n_p, hold);
        warnings.extend(crate::pmsm::checks::noise::input_noise_notice(dq.views(), setup, &motor));
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
        input,
        cable_resistance: options.cable_resistance,
        inverter: options.inverter,
        pwm,
        hold_losses: losses.iter().map(|(h, l, _)| (*h, *l)).collect(),
        start_comparison,
        pmsm_advice,
        pmsm_notes: notes,
    })
}
