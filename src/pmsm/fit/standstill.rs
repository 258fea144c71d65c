//! Standstill commissioning: `R_s`, the inductances and the inverter's voltage error from a
//! locked-rotor log ([`StandstillModel`]), started from an equation-error least-squares
//! estimate, with the injection length that would give `R_s` to ±1 %.

use crate::data::{Channel, Experiment};
use crate::error::{Error, Result};
use crate::estimate::{
    FitResult, PARTS_FLOOR, PARTS_LEVEL, PemOptions, Warning, consecutive_parts, disagreement_of, fit,
    homogeneity_where_estimated,
};
use crate::model::GreyBoxModel;
use crate::pmsm::fit::report::estimate_table;
use crate::pmsm::model::inverter::DEFAULT_RELATIVE_WIDTH;
use crate::pmsm::model::standstill::{StandstillModel, StandstillSetup, WINDING_TEMPERATURE, delayed};
use crate::pmsm::model::temperature::ALPHA_COPPER;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Reference temperature `T_0` \[°C\] of the resistance fitted with a temperature channel.
pub const STANDSTILL_T0: f64 = 20.0;

/// An axis whose rms current is below this fraction of the other's is not excited: its
/// inductance is not estimated and its current not fitted.
pub const UNEXCITED_AXIS: f64 = 0.1;

/// Options of [`fit_standstill`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StandstillOptions {
    /// Pole pairs n_p.
    pub pole_pairs: u32,
    /// `Some(d)`: fit from the reference voltage `ud_ref, uq_ref` applied `d` samples later,
    /// with the inverter's error `v_dt` \[V\] estimated (what firmware knows); `None`: from
    /// the measured terminal voltage `ud, uq`.
    pub reference_delay: Option<usize>,
    /// Width \[A\] of the inverter error's smooth sign, held; `None`: estimated, from
    /// [`DEFAULT_RELATIVE_WIDTH`] × the largest `|i_dq|` of the logs.
    pub width: Option<f64>,
    /// Copper's temperature coefficient α \[1/K\] for `R_s(T)` when the logs carry a
    /// [`WINDING_TEMPERATURE`] channel (then `r_s` is the resistance at [`STANDSTILL_T0`]).
    pub alpha: f64,
    /// The prediction-error options.
    pub pem: PemOptions,
}

impl StandstillOptions {
    /// Defaults for a motor with `pole_pairs`: reference voltage with a delay of 1 sample.
    pub fn new(pole_pairs: u32) -> Self {
        Self { pole_pairs, ..Self::default() }
    }
}

impl Default for StandstillOptions {
    fn default() -> Self {
        Self {
            pole_pairs: 1,
            reference_delay: Some(1),
            width: None,
            alpha: ALPHA_COPPER,
            pem: PemOptions::default(),
        }
    }
}

/// A standstill fit: the estimates, the model's setup and the injection length for `R_s`
/// to ±1 %.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StandstillFit {
    /// The fit (`r_s`, `l_d` and/or `l_q`, `v_dt` with the reference voltage).
    pub fit: FitResult,
    /// The excited axes (0 = d, 1 = q).
    pub axes: Vec<usize>,
    /// `Some(T_0)` when `r_s` is the resistance at `T_0` \[°C\] (a temperature channel).
    pub t0: Option<f64>,
    /// Width \[A\] of the inverter error's smooth sign (estimated or given).
    pub width: f64,
    /// Duration of the logs \[s\].
    pub duration: f64,
    /// Injection length \[s\] of the same kind for a 95 % interval of `r_s` of ±1 %:
    /// `duration · (half-width / 1 %)²` (intervals shrink as `1/√N` for repeated injections).
    pub injection_for_one_percent: f64,
}

/// Consecutive parts the logs are cut into for the self-consistency check of
/// [`fit_standstill`]: two, the halves of a test that injects on one axis and then on the
/// other (the drive simulator's). With four, the quarters that inject only small currents
/// took `r_s` and `v_dt` 5 standard errors from the truth on a noise-free model (their
/// intervals understate a weakly identified part's error), a false alarm on a good log.
pub const STANDSTILL_PARTS: usize = 2;

/// Fewest samples each part of the self-consistency check must hold (shorter logs are not
/// checked).
pub const STANDSTILL_PART_SAMPLES: usize = 200;

/// Fits the standstill model to locked-rotor logs (jointly): channels `id, iq` \[A\],
/// `ud, uq` or `ud_ref, uq_ref` \[V\], `theta_m` \[rad\] (for the inverter error's direction)
/// and optionally [`WINDING_TEMPERATURE`] \[°C\]. The excited axes are those whose rms
/// current reaches [`UNEXCITED_AXIS`] of the other's.
///
/// Then the self-consistency check (issue 43): the logs cut into [`STANDSTILL_PARTS`]
/// consecutive parts, each fitted alone (the whole fit's axes, from its estimate, the
/// width held at its), and Cochran's Q of every parameter over the parts that estimate it
/// ([`crate::estimate::homogeneity_where_estimated`], family level 1e-3, Bonferroni; parts
/// that agree to 1e-5 relative agree). Disagreement makes the fit untrusted
/// (`segments_disagree`): something the model holds constant changed along the test (a
/// winding heating without a logged temperature), and the intervals do not show it.
///
/// # Errors
/// [`Error::MissingChannel`] naming a channel the options need; [`Error::InvalidOption`]
/// (`width`) for a bad width, (`log`) for logs whose current is zero; those of [`fit`].
pub fn fit_standstill(experiments: &[Experiment], options: &StandstillOptions) -> Result<StandstillFit> {
    let whole = fit_once(experiments, options, None)?;
    let Some(warning) = parts_warning(experiments, options, &whole) else {
        return Ok(whole);
    };
    let warnings = whole.fit.warnings.iter().cloned().chain([warning]).collect();
    Ok(StandstillFit { fit: FitResult { warnings, ..whole.fit }, ..whole })
}

/// The untrusted `segments_disagree` warning of [`fit_standstill`]'s self-consistency
/// check, or `None` when the parts agree, are too short, or fewer than two can be fitted.
fn parts_warning(
    experiments: &[Experiment],
    options: &StandstillOptions,
    whole: &StandstillFit,
) -> Option<Warning> {
    // A part that starts within an injection needs the reference applied before its first
    // sample: the delay is applied on the whole logs, and the parts fitted without one.
    let applied = match options.reference_delay {
        Some(d) if d > 0 => {
            experiments.iter().map(|e| delayed_reference(e, d)).collect::<Result<Vec<_>>>().ok()?
        }
        _ => experiments.to_vec(),
    };
    let parts = consecutive_parts(&applied, STANDSTILL_PARTS, STANDSTILL_PART_SAMPLES).ok()?;
    let held = StandstillOptions {
        width: Some(whole.width),
        reference_delay: options.reference_delay.map(|_| 0),
        ..options.clone()
    };
    // Each part at the whole test's axes; an inductance is compared over the parts that
    // excite its axis (another part's is a guess from the noise, its interval no claim).
    let fits: Vec<FitResult> = parts
        .par_iter()
        .filter_map(|p| {
            let fit = fit_once(p, &held, Some(whole)).ok()?.fit;
            let own = excited(currents(p).ok()?.0);
            let parameters = fit
                .parameters
                .iter()
                .filter(|q| match q.name.as_str() {
                    "l_d" => own.contains(&0),
                    "l_q" => own.contains(&1),
                    _ => true,
                })
                .cloned()
                .collect();
            Some(FitResult { parameters, ..fit })
        })
        .collect();
    if fits.len() < 2 {
        return None;
    }
    let detail = disagreement_of(&homogeneity_where_estimated(&fits, PARTS_FLOOR), PARTS_FLOOR, PARTS_LEVEL)?;
    Some(Warning::untrusted(
        "segments_disagree",
        format!(
            "fitted alone, the {} consecutive parts of the test disagree beyond their intervals: {detail}. Something \
             the standstill model holds constant changed along the test (the winding's temperature: log it as \
             `{WINDING_TEMPERATURE}`; the inductance with the current's level; the inverter's error), so the \
             estimates carry an error their intervals do not show",
            fits.len()
        ),
    ))
}

/// The sums of `i_d²` and `i_q²` \[A²\], the largest `|i_dq|` \[A\] and the duration \[s\] of
/// `experiments`.
///
/// # Errors
/// [`Error::MissingChannel`] for a log without `id` or `iq`.
fn currents(experiments: &[Experiment]) -> Result<([f64; 2], f64, f64)> {
    let (mut sq, mut i_max, mut duration) = ([0.0_f64; 2], 0.0_f64, 0.0);
    for e in experiments {
        let (i_d, i_q) = (e.channel("id")?, e.channel("iq")?);
        for k in 0..e.len() {
            sq[0] += i_d[k] * i_d[k];
            sq[1] += i_q[k] * i_q[k];
            i_max = i_max.max(i_d[k].hypot(i_q[k]));
        }
        duration += e.len() as f64 * e.h();
    }
    Ok((sq, i_max, duration))
}

/// The excited axes (0 = d, 1 = q) of sums of squared currents `sq`: those that reach
/// [`UNEXCITED_AXIS`] of the larger's rms.
fn excited(sq: [f64; 2]) -> Vec<usize> {
    let rms_max = sq[0].max(sq[1]);
    (0..2).filter(|&a| sq[a] >= UNEXCITED_AXIS * UNEXCITED_AXIS * rms_max).collect()
}

/// `e` with its reference voltage `ud_ref, uq_ref` as the motor receives it `d` samples
/// later (0 before the first arrives, as the model takes it).
///
/// # Errors
/// [`Error::MissingChannel`] for a log without the reference.
fn delayed_reference(e: &Experiment, d: usize) -> Result<Experiment> {
    let channels = e
        .channels()
        .iter()
        .map(|c| match c.name.as_str() {
            "ud_ref" | "uq_ref" => Channel::new(c.name.clone(), c.unit.clone(), delayed(&c.values, d)),
            _ => c.clone(),
        })
        .collect();
    e.channel("ud_ref")?;
    e.channel("uq_ref")?;
    Ok(Experiment::try_new(e.name(), e.h(), channels)?.with_t0(e.t0()))
}

/// One standstill fit of `experiments`, without the self-consistency check, from the
/// least-squares start or, with `from` (a part of a fitted test), at its axes and from its
/// estimates.
fn fit_once(
    experiments: &[Experiment],
    options: &StandstillOptions,
    from: Option<&StandstillFit>,
) -> Result<StandstillFit> {
    let (sq, i_max, duration) = currents(experiments)?;
    if i_max <= 0.0 || i_max.is_nan() {
        return Err(Error::InvalidOption {
            option: "log".into(),
            reason: "the current is zero throughout: a standstill test injects current".into(),
        });
    }
    // A part of a fitted test models the whole test's axes: an axis it does not excite then
    // takes its direction from the model's current, not from the measured noise.
    let axes = match from {
        Some(whole) => whole.axes.clone(),
        None => excited(sq),
    };
    let temperature = experiments
        .iter()
        .all(|e| e.get(WINDING_TEMPERATURE).is_some())
        .then_some((STANDSTILL_T0, options.alpha));
    let width_start = options.width.unwrap_or(DEFAULT_RELATIVE_WIDTH * i_max);
    let setup = StandstillSetup {
        pole_pairs: options.pole_pairs,
        axes: axes.clone(),
        reference_delay: options.reference_delay,
        width: options.width,
        temperature,
    };
    let probe = StandstillModel::new(setup.clone(), [1.0, 1e-3, 1e-3, 1.0, width_start])?;
    let mut start = equation_error_start(&probe, experiments, width_start)?;
    if options.reference_delay.is_some() && options.width.is_none() {
        start.push(width_start);
    }
    let mut nominal = [start[0], start[1], start[1], 1.0, width_start];
    for (j, &a) in axes.iter().enumerate() {
        nominal[1 + a] = start[1 + j];
    }
    let model = StandstillModel::new(setup, nominal)?;
    // A part of a fitted test starts where the whole fit ended, parameter by parameter.
    if let Some(from) = from {
        for (v, p) in start.iter_mut().zip(model.parameters()) {
            if let Some(q) = from.fit.parameter(&p.name) {
                *v = q.value;
            }
        }
    }
    let result = fit(&model, experiments, &start, &options.pem)?;
    let width = result.parameter("width").map_or(width_start, |p| p.value);
    let injection = result.parameter("r_s").map_or(f64::NAN, |p| {
        let half = 0.5 * (p.ci95[1] - p.ci95[0]) / p.value;
        duration * (half / 0.01).powi(2)
    });
    Ok(StandstillFit {
        fit: result,
        axes,
        t0: temperature.map(|(t0, _)| t0),
        width,
        duration,
        injection_for_one_percent: injection,
    })
}

/// The start (without the width): per axis the equation-error least squares of
/// `Δi[k] = (h/L) (u − R f i + V_dt e)[k]` (forward Euler; `f` the temperature factor),
/// solved by SVD; `R_s` and `V_dt` from the first axis. Non-positive values (a log too noisy for the Euler regression) fall back
/// to magnitudes of the data.
fn equation_error_start(model: &StandstillModel, experiments: &[Experiment], width: f64) -> Result<Vec<f64>> {
    let setup = model.setup();
    let with_v = setup.reference_delay.is_some();
    let prepared = experiments.iter().map(|e| model.prepare(e)).collect::<Result<Vec<_>>>()?;
    let h = experiments.first().map_or(1.0, Experiment::h);
    let mut out = vec![f64::NAN; 1 + setup.axes.len() + usize::from(with_v)];
    for (j, &a) in setup.axes.iter().enumerate() {
        let (mut rows, mut rhs) = (Vec::new(), Vec::new());
        for (e, inputs) in experiments.iter().zip(&prepared) {
            let i = e.channel(if a == 0 { "id" } else { "iq" })?;
            for k in 0..e.len().saturating_sub(1) {
                let (u, dir, f) = inputs.at(a, k, width);
                rows.push([u, -f * i[k], dir]);
                rhs.push(i[k + 1] - i[k]);
            }
        }
        let cols = if with_v { 3 } else { 2 };
        let x = DMatrix::from_fn(rows.len(), cols, |r, c| rows[r][c]);
        let b = DVector::from_vec(rhs);
        let c = x.svd(true, true).solve(&b, 1e-12).map_err(|m| Error::Numerical {
            context: "standstill start (least squares)".into(),
            reason: m.into(),
        })?;
        let l = h / c[0];
        let r = c[1] / c[0];
        out[1 + j] = if l > 0.0 && l.is_finite() { l } else { 1e-3 };
        if j == 0 {
            out[0] = if r > 0.0 && r.is_finite() { r } else { 1.0 };
            if with_v {
                out[1 + setup.axes.len()] = (c[2] / c[0]).max(0.0);
            }
        }
    }
    Ok(out)
}

impl std::fmt::Display for StandstillFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let axes: Vec<&str> = self.axes.iter().map(|&a| if a == 0 { "d" } else { "q" }).collect();
        writeln!(
            f,
            "Standstill fit (locked rotor; axes {}; {:.3} s of logs{}):",
            axes.join(", "),
            self.duration,
            self.t0.map_or(String::new(), |t| format!("; r_s at {t} °C from the winding temperature"))
        )?;
        write!(f, "{}", estimate_table(&self.fit))?;
        let rms: Vec<String> = self.fit.fit.rms_residual.iter().map(|x| format!("{x:.4e}")).collect();
        writeln!(f, "\nrms current residual [A]: {}", rms.join(", "))?;
        if self.fit.parameter("v_dt").is_some() {
            writeln!(
                f,
                "v_dt: the inverter's per-phase voltage error (dead time and device drop), its sign smoothed over \
                 width = {:.3e} A",
                self.width
            )?;
        }
        writeln!(
            f,
            "injection for r_s to ±1 % (95 %): {:.3} s of the same kind of test",
            self.injection_for_one_percent
        )?;
        for w in &self.fit.warnings {
            writeln!(f, "{}{}: {}", if w.untrusted { "untrusted, " } else { "" }, w.code, w.message)?;
        }
        let verdict = if self.fit.trusted() { "trusted" } else { "NOT to be trusted" };
        writeln!(f, "fit {verdict}")
    }
}
