//! The nuisance parameters of a reference-voltage input, estimated by search around the
//! fit: the computational delay (integer, 0–3 samples), the modulator's angle advance
//! (continuous, golden-section search), the bandwidth of the phase-locked loop whose speed
//! the controller advances the reference with, and the width of the dead-time model's
//! smooth sign (golden-section search on their logarithms). Each candidate is a whole fit;
//! the lowest loss wins (MODEL.md §4: the delay and the controller's angle are properties of
//! the drive, not of the motor).

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{FitResult, ParameterEstimate};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::fit::report::delay_parameter;
use crate::pmsm::fit::search::{SPEED_PLL_RANGE, golden_search};
use crate::pmsm::fit::workflow::{fit_dq, fit_pmsm};
use crate::pmsm::log::DqLogs;
use crate::pmsm::log::peak_current;
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::inverter::InverterModel;
use crate::pmsm::model::pwm::PwmInverter;
use crate::pmsm::options::PmsmFitOptions;
use nalgebra::{DMatrix, DVector};

/// Delays tried \[samples\].
pub const DELAYS: std::ops::RangeInclusive<usize> = 0..=3;
/// Range of the modulator angle advance searched \[ω_e h\].
pub const ADVANCE_RANGE: (f64, f64) = (-1.0, 4.0);

/// What to estimate besides the motor's parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InputSearch {
    /// The computational delay, 0–3 samples.
    pub delay: bool,
    /// The modulator's angle advance, in units of `ω_e h`, in [`ADVANCE_RANGE`] (after the
    /// delay: the integer delay and the continuous advance together place the voltage).
    pub advance: bool,
    /// The bandwidth of the controller's speed estimate (needs `theta_m`).
    pub speed_pll: bool,
    /// The width of the dead-time model's smooth sign (with `options.inverter`): the
    /// current ripple blurs the switch-over, by an amount the log does not say.
    pub dead_time_width: bool,
}

/// Fits with the reference voltage of `options.input` (1 sample, 1.5 ω_e h if it is the
/// terminal voltage), estimating what `search` asks for, and returns the fit with the lowest
/// loss among those that converged; its notes give the search.
///
/// # Errors
/// Those of [`fit_pmsm`]; [`Error::Numerical`] when no candidate converges.
pub fn fit_estimating_input(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    search: InputSearch,
) -> Result<PmsmFit> {
    if options.pwm.is_some() {
        return with_drive_timing(experiments, options, search);
    }
    // The logs validated once for the search's fits.
    let dq = DqLogs::try_new(experiments)?;
    let (delay0, advance, pll0) = match options.input {
        VoltageInput::Reference { delay, advance, speed_pll } => (delay, advance, speed_pll),
        VoltageInput::Terminal => (1, 1.5, None),
    };
    // Every candidate starts from the fit at the given input (a least-squares start at a
    // wrong delay can be unusable, e.g. a negative resistance).
    let first = fit_dq(
        &dq,
        &PmsmFitOptions {
            skip_setup_checks: true,
            input: VoltageInput::Reference { delay: delay0, advance, speed_pll: pll0 },
            ..options.clone()
        },
    )?;
    let nuisance = options.inverter.map(|_| "v_dt");
    let start: Vec<f64> = options
        .model
        .parameter_names()
        .iter()
        .copied()
        .chain(nuisance)
        .map(|n| first.parameter(n).map_or(f64::NAN, |p| p.value))
        .collect();
    // The options of a candidate; candidates skip the setup checks, the final fit runs them.
    let options_at =
        |delay: usize, advance: f64, speed_pll: Option<f64>, width: Option<f64>| PmsmFitOptions {
            input: VoltageInput::Reference { delay, advance, speed_pll },
            inverter: options.inverter.map(|i| InverterModel { width: width.or(i.width), ..i }),
            start: Some(start.clone()),
            ..options.clone()
        };
    let fit_with = |delay: usize, advance: f64, speed_pll: Option<f64>, width: Option<f64>| {
        let o = options_at(delay, advance, speed_pll, width);
        fit_dq(&dq, &PmsmFitOptions { skip_setup_checks: true, ..o })
    };
    let fit_at = |delay: usize, speed_pll: Option<f64>| fit_with(delay, advance, speed_pll, None);
    // A candidate that cannot be fitted (diverging simulation, no convergence) loses.
    let loss = |f: Result<PmsmFit>| match f {
        Ok(f) if f.solver.success => Ok(f.fit.loss),
        Ok(_)
        | Err(Error::Numerical { .. } | Error::SimulationDiverged { .. } | Error::InvalidParameter { .. }) => {
            Ok(f64::INFINITY)
        }
        Err(e) => Err(e),
    };
    let mut notes = Vec::new();
    let mut delays_tried: Vec<(usize, f64)> = Vec::new();
    let delay = if search.delay {
        let mut tried = Vec::new();
        for d in DELAYS {
            tried.push((d, loss(fit_at(d, pll0))?));
        }
        let best = tried.iter().min_by(|a, b| a.1.total_cmp(&b.1)).map_or(delay0, |t| t.0);
        let text: Vec<String> = tried.iter().map(|(d, l)| format!("{d}: {l:.6e}")).collect();
        notes.push(format!(
            "computational delay estimated as {best} sample(s) by the lowest loss ({})",
            text.join(", ")
        ));
        delays_tried = tried;
        best
    } else {
        delay0
    };
    let advance = if search.advance {
        let a = golden_search(ADVANCE_RANGE, false, |a| loss(fit_with(delay, a, pll0, None)))?;
        notes.push(format!("modulator angle advance estimated as {a:.4} ω_e h by the lowest loss"));
        a
    } else {
        advance
    };
    let fit_at = |delay: usize, speed_pll: Option<f64>| fit_with(delay, advance, speed_pll, None);
    let speed_pll = if search.speed_pll {
        // Profiled: the motor's estimate and initial states of the fit at this delay and
        // advance are held while the bandwidth is searched by simulation alone (no fit per
        // candidate); the fit below then re-estimates them at the best bandwidth.
        let base = if search.delay || search.advance { fit_at(delay, pll0)? } else { first.clone() };
        let profile = Profile::new(&base, experiments)?;
        let alpha = golden_search(SPEED_PLL_RANGE, true, |a| {
            let input = VoltageInput::Reference { delay, advance, speed_pll: Some(a) };
            profile.loss(&PmsmFit { input, ..base.clone() }, experiments)
        })?;
        notes.push(format!(
            "speed estimate of the angle advance: phase-locked loop of {alpha:.1} rad/s ({:.1} Hz), by the \
             lowest loss",
            alpha / std::f64::consts::TAU
        ));
        Some(alpha)
    } else {
        pll0
    };
    let width = match (search.dead_time_width, options.inverter) {
        (true, Some(_)) => {
            let peak = peak_current(dq.views());
            let range = (1e-3 * peak, 0.3 * peak);
            let w = golden_search(range, true, |w| loss(fit_with(delay, advance, speed_pll, Some(w))))?;
            notes.push(format!("dead-time sign width estimated as {w:.4} A by the lowest loss"));
            Some(w)
        }
        (true, None) => {
            return Err(Error::InvalidOption {
                option: "dead-time width".into(),
                reason: "estimating the width needs the inverter model".into(),
            });
        }
        (false, _) => None,
    };
    let best = fit_dq(&dq, &options_at(delay, advance, speed_pll, width))?;
    if !best.solver.success && (search.delay || search.advance || search.speed_pll || search.dead_time_width)
    {
        return Err(Error::Numerical {
            context: "input estimate".into(),
            reason: format!(
                "the fit at the best delay {delay} does not converge: {}",
                best.solver.termination
            ),
        });
    }
    let estimated = (!delays_tried.is_empty()).then(|| delay_set(&delays_tried, delay, best.fit.dof));
    let PmsmFit { report, mut pmsm_notes, .. } = best.clone();
    pmsm_notes.append(&mut notes);
    let parameters = report
        .parameters
        .iter()
        .filter(|p| p.name != "delay_samples")
        .cloned()
        .chain(delay_parameter(best.input, estimated))
        .collect();
    Ok(PmsmFit { report: FitResult { parameters, ..report }, pmsm_notes, ..best })
}

/// The loss of a fit whose input changes, with its free parameters and initial states
/// re-estimated to first order (variable projection; Golub & Pereyra, *SIAM J. Numer.
/// Anal.* 10 (1973) 413–432): half the part of the simulated output error that the
/// Jacobian at the base fit cannot explain, `½ (‖r‖² − ‖Qᵀr‖²)`, `J = QR` by central
/// differences of the simulation in each free entry. A search over the input then costs a
/// simulation per candidate instead of a fit, and finds the minimum of the fitted loss,
/// not that of the loss at the base fit's biased estimate.
struct Profile {
    q: DMatrix<f64>,
    /// The measured outputs, stacked as the Jacobian's rows.
    y: DVector<f64>,
}

impl Profile {
    /// The projection at `base` on `experiments`.
    ///
    /// # Errors
    /// Those of [`PmsmFit::comparisons`].
    fn new(base: &PmsmFit, experiments: &[Experiment]) -> Result<Self> {
        let outputs = |f: &PmsmFit| -> Result<Vec<f64>> { Ok(f.simulated_outputs(experiments)?.concat()) };
        let mut columns = Vec::new();
        let free = |p: &ParameterEstimate| !p.fixed && p.value.is_finite();
        let n_par = base.parameters.len();
        for j in 0..n_par + base.initial_states.len() {
            let entry = |f: &PmsmFit| {
                if j < n_par { f.parameters[j].clone() } else { f.initial_states[j - n_par].clone() }
            };
            if !free(&entry(base)) {
                continue;
            }
            let at = |x: f64| {
                let mut f = base.clone();
                let p = if j < n_par {
                    &mut f.report.parameters[j]
                } else {
                    &mut f.report.initial_states[j - n_par]
                };
                p.value = x;
                outputs(&f)
            };
            let v = entry(base).value;
            let step = 1e-6 * v.abs().max(1e-3);
            let (hi, lo) = (at(v + step)?, at(v - step)?);
            columns.push(hi.iter().zip(&lo).map(|(a, b)| (a - b) / (2.0 * step)).collect::<Vec<f64>>());
        }
        let rows = columns.first().map_or(0, Vec::len);
        let j = DMatrix::from_fn(rows, columns.len(), |r, c| columns[c][r]);
        let y = base.comparisons(experiments)?.into_iter().flat_map(|c| c.y).collect::<Vec<f64>>();
        Ok(Self { q: j.qr().q(), y: DVector::from_vec(y) })
    }

    /// The projected loss of `fit` (the base fit with another input); ∞ when the simulation
    /// diverges.
    ///
    /// # Errors
    /// Those of [`PmsmFit::comparisons`] but a diverging simulation.
    fn loss(&self, fit: &PmsmFit, experiments: &[Experiment]) -> Result<f64> {
        let y_hat = match fit.simulated_outputs(experiments) {
            Ok(c) => c.concat(),
            Err(
                Error::SimulationDiverged { .. } | Error::InvalidParameter { .. } | Error::Numerical { .. },
            ) => {
                return Ok(f64::INFINITY);
            }
            Err(e) => return Err(e),
        };
        let r = &self.y - DVector::from_vec(y_hat);
        let explained = self.q.tr_mul(&r);
        Ok(0.5 * (r.norm_squared() - explained.norm_squared()).max(0.0))
    }
}

/// The 95 % set of delays `[lo, hi]` around `best`: those whose loss a likelihood-ratio
/// test does not reject, `(V_d − V_min) dof / V_min < χ²₁(0.95) = 3.841` (Gaussian errors,
/// `V = ½E²`, `σ̂² = E²/dof`; Ljung, *System Identification*, 16.4), widened to a contiguous
/// range.
fn delay_set(tried: &[(usize, f64)], best: usize, dof: usize) -> [usize; 2] {
    let v_min = tried.iter().map(|t| t.1).fold(f64::INFINITY, f64::min);
    let kept =
        tried.iter().filter(|(_, v)| v_min > 0.0 && (v - v_min) * dof as f64 / v_min < 3.841).map(|t| t.0);
    let lo = kept.clone().min().unwrap_or(best).min(best);
    let hi = kept.max().unwrap_or(best).max(best);
    [lo, hi]
}

/// A PWM fit (`options.pwm`) at the drive's timing (`search`: the computational delay, the
/// angle advance, the controller's speed estimate) found with the averaged inverter model
/// (`--dead-time estimate --dead-time-mask auto`, whose search costs about a second where
/// one through the PWM model costs a fit of a minute per candidate): the delay and the
/// controller's angle are the drive's, not the inverter's (MODEL.md §4). The timing fit's
/// `delay_samples` and a note on where the timing came from join the PWM fit's report.
///
/// # Errors
/// Those of [`fit_estimating_input`] and [`fit_pmsm`]; [`crate::Error::InvalidOption`] for a
/// search of the averaged model's dead-time width (the PWM model has its own leg state).
fn with_drive_timing(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    search: InputSearch,
) -> Result<PmsmFit> {
    if search.dead_time_width {
        return Err(crate::Error::InvalidOption {
            option: "dead-time-width".into(),
            reason: "the PWM inverter has its own leg state: drop --dead-time-width, see --leg-state-width"
                .into(),
        });
    }
    let pwm = options.pwm.map(|p| PwmInverter { search_speed_pll: search.speed_pll, ..p });
    if !(search.delay || search.advance) {
        return fit_pmsm(experiments, &PmsmFitOptions { pwm, ..options.clone() });
    }
    let averaged = crate::pmsm::options::averaged_inverter(options);
    let timing = fit_estimating_input(experiments, &averaged, InputSearch { speed_pll: false, ..search })?;
    let fit = fit_pmsm(experiments, &PmsmFitOptions { input: timing.input, pwm, ..options.clone() })?;
    let VoltageInput::Reference { delay, advance, .. } = timing.input else {
        return Ok(fit);
    };
    let note = format!(
        "the drive's timing from a fit of the averaged inverter model (dead time estimated, its mask auto): delay \
         {delay} sample(s), angle advance {advance:.4} ω_e h"
    );
    let delay = timing.parameter("delay_samples").cloned();
    let parameters =
        fit.report.parameters.iter().filter(|p| p.name != "delay_samples").cloned().chain(delay).collect();
    let pmsm_notes = std::iter::once(note).chain(fit.pmsm_notes.iter().cloned()).collect();
    Ok(PmsmFit { report: FitResult { parameters, ..fit.report.clone() }, pmsm_notes, ..fit })
}
