//! `--method iv`: the errors-in-variables fit of a log whose voltage (or current) carries
//! noise, by refined instrumental variables on the exact inverse model.
//!
//! Output error drives the model with the logged voltage; noise on that voltage then enters
//! the simulated current and correlates with the residual, which biases the estimate (by
//! about two standard errors on a 7 s record with 1 V of noise: `examples/coverage_drive.rs`).
//! The inverse model turns the roles round: the exact step solved for its voltage term
//! (`spm::inverse`, MODEL.md §4), `ε_k = u[k] − û_k(θ; i[k], i[k+1])`, is linear in the
//! measured currents and holds the voltage noise alone, white, in its error. The currents'
//! noise still sits in the regressors `∂û/∂θ`; the instruments replace it with the
//! currents an auxiliary model simulates from the logged voltage (output error at the
//! current estimate: the simplified refined IV of Young, *Recursive Estimation and
//! Time-Series Analysis*, 2nd ed., 2011, 7.2), taken one interval earlier so that they hold
//! the voltage of interval k − 1 and not that of k, whose noise is in `ε_k` (Söderström,
//! *Automatica* 43 (2007) 939–958, 4: instruments uncorrelated with the equation error).
//! Iterated with the auxiliary model updated to each estimate until the step is below
//! 1e-10 relative; started from the output-error fit, whose hold it keeps.
//!
//! The interior-magnet model has no scalar inverse: there the equation error is the one-step
//! current error `i[k+1] − x⁺(θ, k, i[k])` of its exact step, with the same instruments
//! (the step's sensitivities at the simulated current of interval k − 1, whose voltage is
//! not interval k's: `estimate::iv::one_step_sums`).
//!
//! Where it holds: both models on the terminal voltage, any hold, cable resistance. Not
//! yet: the reference voltage and the inverter model (the applied voltage is then a model
//! output, not a measurement, and its error is the inverter's, not noise), per-log and
//! fixed parameters.

use super::iv_report::{Solved, report};
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::iv::{IvSums, one_step_sums};
use crate::estimate::{FitResult, Warning, WeightingKind, paired_difference_variance};
use crate::model::{GreyBoxModel, Prepared};
use crate::pmsm::checks::noise_floor::poor_fit_is_noise;
use crate::pmsm::fit::hold::{GIVE_THE_HOLD, HOLD_AMBIGUOUS_Z, hardly_chosen, largest_difference};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::fit::workflow::fit_pmsm;
use crate::pmsm::log::DqLogs;
use crate::pmsm::model::interval::{C64, VoltageHold, VoltageInput};
use crate::pmsm::model::ipm::PmsmIpm;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::model::spm::PmsmSpm;
use crate::pmsm::options::{HoldChoice, PmsmFitOptions};
use crate::simulate::{SimOptions, simulate};

/// Which criterion a PMSM fit minimises or solves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Estimator {
    /// The prediction-error method ([`fit_pmsm`]), or refined instrumental variables
    /// ([`fit_pmsm_iv_after`]) when its fit finds the logged voltage's noise biasing it
    /// (warning `voltage_noise_bias`) and the options allow them ([`check_options`]).
    #[default]
    Auto,
    /// The prediction-error method ([`fit_pmsm`]).
    PredictionError,
    /// Refined instrumental variables on the inverse model ([`fit_pmsm_iv`]).
    InstrumentalVariables,
}

/// Most refinements of the instruments and estimate.
pub const IV_MAX_ITERATIONS: usize = 30;

/// Relative step below which the iteration has converged.
pub const IV_STEP_TOLERANCE: f64 = 1e-10;

/// Refuses the options the inverse model does not cover (module documentation).
///
/// # Errors
/// [`Error::InvalidOption`] (option `method`) naming the option.
pub fn check_options(options: &PmsmFitOptions) -> Result<()> {
    let no = |what: &str| {
        Err(Error::InvalidOption {
            option: "method".into(),
            reason: format!("iv (instrumental variables) does not take {what} yet; use --method pem"),
        })
    };
    if options.input != VoltageInput::Terminal || options.inverter.is_some() {
        return no("the reference voltage or the inverter model (it inverts the measured terminal voltage)");
    }
    if !options.pem.per_experiment.is_empty() || !options.fixed.is_empty() || !options.fixed_values.is_empty()
    {
        return no("per-log or fixed parameters");
    }
    if options.thermal.is_some() {
        return no("temperature estimates (--t0)");
    }
    let pem = &options.pem;
    if !options.bounds.is_empty() {
        return no("bounds (--bounds)");
    }
    if pem.horizon.is_some() || pem.prefilter.is_some() || pem.huber.is_some() || pem.output_weights.is_some()
    {
        return no(
            "the output-error criterion's options (--horizon, --prefilter, --huber, --output-weights)",
        );
    }
    if pem.weighting != WeightingKind::Uniform {
        return no("sample weights (--weighting)");
    }
    Ok(())
}

/// One log ready for the IV sums: its prepared inputs and measured currents.
struct Log {
    prep: Prepared<<PmsmSpm as GreyBoxModel>::Inputs>,
    i: Vec<C64>,
}

/// The IV sums at θ over every log: the equation errors and Jacobians at the measured
/// currents, the instruments at the currents the model simulates at θ, one interval back.
fn sums(model: &PmsmSpm, logs: &[Log], theta: &[f64]) -> Result<IvSums> {
    let mut acc = IvSums::new(2, 3);
    for log in logs {
        let c = model.coefficients(theta, &log.prep.inputs)?;
        let sim = simulate(model, &log.prep, theta, &SimOptions::default())?;
        let i_sim: Vec<C64> = sim.chunks_exact(2).map(|v| C64::new(v[0], v[1])).collect();
        acc.start_experiment();
        let mut before: Option<[C64; 3]> = None;
        for k in 0..log.i.len().saturating_sub(1) {
            let inv = model.inverse_step(&c, &log.prep.inputs, k);
            let (u_hat, du) = inv.voltage(log.i[k], log.i[k + 1]);
            let (_, dz) = inv.voltage(i_sim[k], i_sim[k + 1]);
            if let Some(z) = before {
                let eps = inv.u - u_hat;
                let d = [-du[0].re, -du[1].re, -du[2].re, -du[0].im, -du[1].im, -du[2].im];
                let z = [-z[0].re, -z[1].re, -z[2].re, -z[0].im, -z[1].im, -z[2].im];
                acc.add(&[eps.re, eps.im], &d, &z);
            }
            before = Some(dz);
        }
        acc.end_experiment();
    }
    Ok(acc)
}

/// Fits an SPM model by refined instrumental variables on the exact inverse model (module
/// documentation), started from [`fit_pmsm`] with the same options, whose hold, checks,
/// warnings and goodness of fit the report keeps; the parameters, derived quantities,
/// correlation, uncertainty and solver are the IV estimate's. Where the automatic hold
/// hardly chose, IV also runs at the other hold, and the fit may be untrusted
/// (`hold_ambiguous`, [`fit_pmsm_iv_after`]).
///
/// # Errors
/// [`Error::InvalidOption`] (`method`) for options the inverse model does not cover; those
/// of [`fit_pmsm`]; [`Error::Numerical`] when the instruments do not determine every
/// parameter or the iteration leaves the positive parameters, its reason followed by the
/// untrusted warnings of the output-error fit it started from.
pub fn fit_pmsm_iv(experiments: &[Experiment], options: &PmsmFitOptions) -> Result<PmsmFit> {
    check_options(options)?;
    let oe = fit_pmsm(experiments, options)?;
    let untrusted: Vec<String> =
        oe.report.warnings.iter().filter(|w| w.untrusted).map(|w| w.code.clone()).collect();
    fit_pmsm_iv_after(oe, experiments, options).map_err(|e| named_by(e, &untrusted))
}

/// A failed IV fit's error `e` with the untrusted warnings `codes` of the output-error fit IV
/// started from appended, where there are any: what went wrong before the instruments did
/// (a speed in rpm, a wrong pole-pair count), which the bare numerical failure does not say.
/// Errors other than numerical ones are returned as they are.
fn named_by(e: Error, codes: &[String]) -> Error {
    match e {
        Error::Numerical { context, reason } if !codes.is_empty() => Error::Numerical {
            context,
            reason: format!(
                "{reason}; the output-error fit IV starts from is untrusted ({}): --method pem reports it with \
                 those warnings",
                codes.join(", ")
            ),
        },
        e => e,
    }
}

/// [`fit_pmsm_iv`] from the output-error fit `oe` of the same `experiments` and `options`
/// (the automatic choice of [`Estimator::Auto`] has it already): the IV estimate started
/// from it, its hold, checks, warnings (but `input_noise` and `voltage_noise_bias`, which
/// this method is for) and goodness of fit kept. Where the automatic hold fitted both holds
/// to output-error losses within
/// [`DQ_DECISIVE`](crate::pmsm::thresholds::DQ_DECISIVE) of each other (the data hardly
/// choose), IV runs at the other hold too, and estimates more than [`HOLD_AMBIGUOUS_Z`]
/// standard errors of their difference apart make the fit untrusted (`hold_ambiguous`):
/// IV's errors are smaller than output error's, against which the hold was chosen, so a
/// difference output error's intervals hide can exceed IV's.
///
/// # Errors
/// As [`fit_pmsm_iv`].
pub fn fit_pmsm_iv_after(
    oe: PmsmFit,
    experiments: &[Experiment],
    options: &PmsmFitOptions,
) -> Result<PmsmFit> {
    let dq = DqLogs::try_new(experiments)?;
    let at_other = other_hold(&oe, &dq, options).map(|hold| PmsmFit { hold, ..oe.clone() });
    let (iv, sums) = iv_at_hold(oe, &dq, options)?;
    let Some(at_other) = at_other.filter(|_| iv.report.warnings.iter().all(|w| w.code != "hold_ambiguous"))
    else {
        return Ok(iv);
    };
    let (other, other_sums) = iv_at_hold(at_other, &dq, options)?;
    let shifts = |s: Option<IvSums>| s.and_then(|s| s.jackknife_shifts());
    let paired = shifts(sums).zip(shifts(other_sums)).and_then(|(a, b)| paired_difference_variance(&a, &b));
    let Some(warning) = hold_ambiguous(&iv, &other, paired.as_deref(), options) else { return Ok(iv) };
    let warnings = iv.report.warnings.iter().cloned().chain([warning]).collect();
    Ok(PmsmFit { report: FitResult { warnings, ..iv.report }, ..iv })
}

/// The hold the automatic choice did not take, when both were fitted, their output-error
/// losses lie within [`DQ_DECISIVE`](crate::pmsm::thresholds::DQ_DECISIVE) of each other
/// (`hold::hardly_chosen`) and no log carries a modulator's reference, which settles the
/// stator hold as in the output-error fit (MODEL.md §4; exp3 with 1 V + 0.03 A: the holds'
/// IV `k_e` 4.8–5.4 standard errors apart, the stator's covering the truth); `None`
/// otherwise (a hold given, a steady-state fit, which has one hold).
fn other_hold(oe: &PmsmFit, dq: &DqLogs<'_>, options: &PmsmFitOptions) -> Option<VoltageHold> {
    let [(a, la), (b, lb)] = oe.hold_losses[..] else { return None };
    let modulator = crate::pmsm::log::modulator_reference(dq.views());
    let open = options.hold == HoldChoice::Auto && !modulator && hardly_chosen(lb, la);
    open.then_some(if oe.hold == a { b } else { a })
}

/// An untrusted `hold_ambiguous` warning when the IV estimates at the two holds differ in
/// any parameter by more than [`HOLD_AMBIGUOUS_Z`] standard errors of their difference:
/// `paired`, the batches' paired jackknife variance of the difference per parameter (in
/// the model's parameter order, [`paired_difference_variance`]), where both fits have it;
/// else (batches that cannot be formed, or one that alone determines a parameter) the
/// combined standard errors `√(se_a² + se_b²)` ([`largest_difference`]), which
/// treat two fits of the same data as independent and hide a difference the data
/// determine well: on the set-aside gym-electric-motor SPM log of moves (a simulator that
/// holds the dq voltage) with 3 V + 0.03 A that test passed 9 of 10 fits at the stator
/// hold with `k_e` covered in 1 of 9 (mean z +2.6). The jackknife's variance has G − 1
/// degrees of freedom (31 on a log long enough for 32 batches): at the fewest batches, 8,
/// a difference of pure noise passes 3 standard errors for one parameter in about 50
/// (Student's t with 7 degrees of freedom), a few hundredths over four parameters, against
/// about 0.5 % at 31.
fn hold_ambiguous(
    iv: &PmsmFit,
    other: &PmsmFit,
    paired: Option<&[f64]>,
    options: &PmsmFitOptions,
) -> Option<Warning> {
    let names = options.model.parameter_names();
    let paired = paired.filter(|v| v.len() == names.len());
    let how =
        if paired.is_some() { "standard errors of their difference" } else { "combined standard errors" };
    let (name, z) = largest_difference(&iv.report, &other.report, names, paired)?;
    (z > HOLD_AMBIGUOUS_Z).then(|| {
        Warning::untrusted(
            "hold_ambiguous",
            format!(
                "the instrumental-variable estimates at the {} and {} voltage holds, whose output-error losses are \
                 close, differ in {name} by {z:.1} {how}: the log does not say how the voltage was held; \
                 {GIVE_THE_HOLD}",
                iv.hold, other.hold
            ),
        )
    })
}

/// The IV fit from the output-error fit `oe` at its hold ([`fit_pmsm_iv_after`] without the
/// other hold), and its sums at the estimate, for the deleted-batch shifts
/// ([`IvSums::jackknife_shifts`]) where the other hold is fitted too; `None` for the
/// steady-state equations.
///
/// # Errors
/// As [`fit_pmsm_iv`].
fn iv_at_hold(oe: PmsmFit, dq: &DqLogs<'_>, options: &PmsmFitOptions) -> Result<(PmsmFit, Option<IvSums>)> {
    check_options(options)?;
    // The steady-state equations the output-error fit chose are fitted by instrumental
    // variables already (on the steady samples); the dynamic recursion from their estimate
    // failed on every 40th row of a moves log and gave l_s +170 % with exit 0 on every 20th.
    if oe.steady_state() {
        let note = "--method iv: the steady-state equations chosen for this log are fitted by instrumental \
                    variables already"
            .to_string();
        let notes = oe.report.notes.iter().cloned().chain([note]).collect();
        return Ok((PmsmFit { report: FitResult { notes, ..oe.report }, ..oe }, None));
    }
    let t0 = std::time::Instant::now();
    let setup =
        PmsmSetup { cable_resistance: options.cable_resistance, ..PmsmSetup::new(oe.pole_pairs, oe.hold) };
    let names = options.model.parameter_names();
    let start: Vec<f64> =
        names.iter().map(|n| oe.parameter(n).map(|p| p.value)).collect::<Option<_>>().ok_or_else(|| {
            Error::Numerical { context: "instrumental variables".into(), reason: "no start".into() }
        })?;
    let floor = poor_fit_is_noise(dq.views(), &oe.report, setup, options);
    let (solved, at) = match options.model {
        MotorKind::Spm => {
            let model = PmsmSpm::from_setup(setup);
            let logs: Vec<Log> = dq
                .views()
                .iter()
                .map(|v| {
                    let i = v.i_d().iter().zip(v.i_q()).map(|(&d, &q)| C64::new(d, q)).collect();
                    Ok(Log { prep: Prepared::new(&model, v.experiment())?, i })
                })
                .collect::<Result<_>>()?;
            iterate(start, |t| sums(&model, &logs, t))?
        }
        MotorKind::Ipm => {
            let model = PmsmIpm::from_setup(setup);
            let preps =
                dq.experiments().iter().map(|e| Prepared::new(&model, e)).collect::<Result<Vec<_>>>()?;
            iterate(start, |t| one_step_sums(&model, &preps, t))?
        }
    };
    Ok((report(oe, solved, t0.elapsed().as_secs_f64(), options.precision.as_deref(), floor), Some(at)))
}

/// Newton steps on the IV equations of `sums` from `theta` (refining the instruments with
/// each estimate) until the step is below [`IV_STEP_TOLERANCE`] relative, at most
/// [`IV_MAX_ITERATIONS`]; the covariance at the end, and the sums there.
///
/// # Errors
/// Those of `sums` and [`IvSums::step`]; [`Error::Numerical`] when a parameter that must be
/// positive (all but the last, `k_e`) leaves the positive range.
fn iterate(mut theta: Vec<f64>, sums: impl Fn(&[f64]) -> Result<IvSums>) -> Result<(Solved, IvSums)> {
    let mut iterations = 0;
    let mut converged = false;
    while iterations < IV_MAX_ITERATIONS && !converged {
        let step = sums(&theta)?.step()?;
        iterations += 1;
        converged = step.iter().zip(&theta).all(|(d, t)| d.abs() <= IV_STEP_TOLERANCE * t.abs());
        for (t, d) in theta.iter_mut().zip(step.iter()) {
            *t += d;
        }
        let positive = theta.len() - 1;
        if theta[..positive].iter().any(|t| t.is_nan() || *t <= 0.0) {
            return Err(Error::Numerical {
                context: "instrumental variables".into(),
                reason: format!(
                    "the iteration left the positive resistance and inductances ({theta:?}): the instruments are \
                     too weak"
                ),
            });
        }
    }
    let at = sums(&theta)?;
    let cov = at.covariance()?;
    Ok(((theta, cov, iterations, converged), at))
}
