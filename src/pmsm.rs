//! PMSM fits in one call: least-squares start, voltage-hold selection, prediction-error
//! fit, derived torque constant and magnet flux.
//!
//! This is what the command line runs. The steps (MODEL.md §4–5):
//! 1. start from the linear least-squares estimate (thesis 5.2.1) unless a start is given;
//! 2. fit with the chosen voltage hold; with [`HoldChoice::Auto`] fit both holds (the
//!    second from the first's estimate) and keep the one with the lower loss — the holds
//!    differ at second order in `ω_e h`, which decides between 10⁻⁴ and 10⁻⁷ accuracy;
//! 3. derive `K_t = √(3/2) K_e` [N m/A] and `ψ_f = √(2/3) K_e / n_p` [V s] with their
//!    standard errors (MODEL.md §2).

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::diagnostics::StartComparison;
use crate::estimate::linear::{MotorKind, least_squares};
use crate::estimate::{DerivedEstimate, FitResult, PemOptions, fit};
use crate::model::{PmsmIpm, PmsmSpm, VoltageHold};
use serde::{Deserialize, Serialize};
use std::time::Instant;

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

/// Options of [`fit_pmsm`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PmsmFitOptions {
    /// Surface (`spm`) or interior (`ipm`) magnets.
    pub model: MotorKind,
    /// Voltage hold.
    pub hold: HoldChoice,
    /// Start values in model order (`r_s, l_s, k_e` or `r_s, l_d, l_q, k_e`); `None` =
    /// linear least-squares estimate.
    pub start: Option<Vec<f64>>,
    /// Parameters held at their start value, by name.
    pub fixed: Vec<String>,
    /// Bounds `(name, lower, upper)` replacing the model's defaults.
    pub bounds: Vec<(String, f64, f64)>,
    /// Options of the prediction-error fit.
    pub pem: PemOptions,
}

/// Fits a PMSM model to one or more logs of one motor (parameters shared unless listed in
/// `options.pem.per_experiment`).
///
/// # Errors
/// [`Error::InvalidOption`] for no experiments, experiments with different pole-pair
/// numbers, a start of the wrong length, an unknown parameter name in `fixed`/`bounds`;
/// [`Error::Numerical`] when the least-squares start cannot be computed (no excitation)
/// or gives a non-positive `R_s`/`L`; and every error of [`crate::estimate::fit`].
///
/// # Example
/// ```no_run
/// use greybox::pmsm::{fit_pmsm, PmsmFitOptions};
/// # fn main() -> greybox::Result<()> {
/// let log = greybox::read_csv("data/sample.csv.gz", 4, &Default::default())?;
/// let fit = fit_pmsm(&[log], &PmsmFitOptions::default())?;
/// println!("{fit}");
/// println!("K_t = {:.5} N m/A", fit.derived("k_t").unwrap().value);
/// # Ok(()) }
/// ```
pub fn fit_pmsm(experiments: &[Experiment], options: &PmsmFitOptions) -> Result<FitResult> {
    let t0 = Instant::now();
    let first = experiments.first().ok_or_else(|| Error::InvalidOption {
        option: "experiments".into(),
        reason: "no log given".into(),
    })?;
    if let Some(e) = experiments.iter().find(|e| e.n_p() != first.n_p()) {
        return Err(Error::InvalidOption {
            option: "pole pairs".into(),
            reason: format!(
                "`{}` has n_p = {} but `{}` has n_p = {}: a joint fit needs one motor",
                e.name(),
                e.n_p(),
                first.name(),
                first.n_p()
            ),
        });
    }
    let names = options.model.parameter_names();
    let mut notes = Vec::new();
    let mut ls_theta = None;
    let start = match &options.start {
        Some(s) => {
            if s.len() != names.len() {
                return Err(Error::InvalidOption {
                    option: "start".into(),
                    reason: format!(
                        "{} values given, the {:?} model has {} ({})",
                        s.len(),
                        options.model,
                        names.len(),
                        names.join(", ")
                    ),
                });
            }
            notes.push("start given by the user".to_string());
            s.clone()
        }
        None => {
            let ls = least_squares(experiments, options.model)?;
            for (n, v) in ls.names.iter().zip(&ls.theta) {
                if n != "k_e" && *v <= 0.0 {
                    return Err(Error::Numerical {
                        context: "least-squares start".into(),
                        reason: format!("`{n}` = {v:e} is not positive; give a start value (--start)"),
                    });
                }
            }
            notes.push(format!(
                "start from linear least squares: {}",
                ls.names
                    .iter()
                    .zip(&ls.theta)
                    .map(|(n, v)| format!("{n} = {v:.6e}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            ls_theta = Some(ls.theta.clone());
            ls.theta
        }
    };
    let holds: &[VoltageHold] = match options.hold {
        HoldChoice::Dq => &[VoltageHold::Dq],
        HoldChoice::Stator => &[VoltageHold::Stator],
        HoldChoice::Auto => &[VoltageHold::Stator, VoltageHold::Dq],
    };
    let mut best: Option<FitResult> = None;
    let mut losses = Vec::new();
    let mut others: Vec<FitResult> = Vec::new();
    for &hold in holds {
        // The second hold starts from the first's estimate: it converges in a few steps.
        let s = match &best {
            Some(b) if b.solver.success => names
                .iter()
                .map(|n| b.parameter(n).map(|p| p.value))
                .collect::<Option<Vec<f64>>>()
                .unwrap_or_else(|| start.clone()),
            _ => start.clone(),
        };
        let r = match options.model {
            MotorKind::Spm => {
                let mut m = PmsmSpm::new(hold);
                configure(m.parameters_mut(), options)?;
                fit(&m, experiments, &s, &options.pem)
            }
            MotorKind::Ipm => {
                let mut m = PmsmIpm::new(hold);
                configure(m.parameters_mut(), options)?;
                fit(&m, experiments, &s, &options.pem)
            }
        };
        let mut r = r?;
        r.hold = Some(hold);
        losses.push((hold, r.fit.loss, r.solver.success));
        let better = match &best {
            None => true,
            Some(b) => {
                (r.solver.success && !b.solver.success)
                    || (r.solver.success == b.solver.success && r.fit.loss < b.fit.loss)
            }
        };
        if better {
            if let Some(b) = best.replace(r) {
                others.push(b);
            }
        } else {
            others.push(r);
        }
    }
    let mut result = best.expect("at least one hold is fitted");
    if let Some(a) = hold_ambiguity(&result, &others, names) {
        result.diagnostics.advice.push(a);
    }
    if losses.len() > 1 {
        notes.push(format!(
            "voltage hold chosen automatically by the lower loss: {}",
            losses.iter().map(|(h, l, _)| format!("{h} {l:.6e}")).collect::<Vec<_>>().join(", ")
        ));
    }
    result.derived = derived(&result, first.n_p());
    if let Some(ls) = ls_theta {
        result.diagnostics.start_comparison = names
            .iter()
            .zip(&ls)
            .filter_map(|(n, &l)| {
                let p = result.parameter(n)?;
                (!p.fixed).then(|| StartComparison {
                    name: n.to_string(),
                    least_squares: l,
                    pem: p.value,
                    difference_percent: 100.0 * (l - p.value) / p.value,
                })
            })
            .collect();
    }
    notes.append(&mut result.notes);
    result.notes = notes;
    result.timing.fit_s = t0.elapsed().as_secs_f64();
    result.timing.total_s = result.timing.fit_s;
    Ok(result)
}

/// Advice when the losses of the two holds are close (ratio below 2) but their estimates
/// differ by more than 3 standard errors: the data do not clearly say how the voltage was
/// held (PWM ripple, dead time, or a voltage column that is not a period mean).
fn hold_ambiguity(best: &FitResult, others: &[FitResult], names: &[&str]) -> Option<String> {
    let other = others.first()?;
    let ratio = other.fit.loss / best.fit.loss;
    if ratio.is_nan() || ratio >= 2.0 {
        return None;
    }
    let (name, z) = names
        .iter()
        .filter_map(|n| {
            let (a, b) = (best.parameter(n)?, other.parameter(n)?);
            Some((*n, ((a.value - b.value) / a.std_error).abs()))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    (z > 3.0).then(|| {
        format!(
            "the {} and {} voltage holds fit almost equally well (loss ratio {ratio:.3}) but their {name} \
             differs by {z:.0} standard errors: the log does not say how the voltage was held; a real \
             inverter holds it in the stator frame (--hold stator); this fit used the {} hold",
            best.hold.map(|h| h.to_string()).unwrap_or_default(),
            other.hold.map(|h| h.to_string()).unwrap_or_default(),
            best.hold.map(|h| h.to_string()).unwrap_or_default(),
        )
    })
}

/// Applies the fixed flags and bounds of `options` to the model's parameter metadata.
fn configure(params: &mut [crate::model::Parameter], options: &PmsmFitOptions) -> Result<()> {
    let unknown = |n: &str, what: &str| Error::InvalidOption {
        option: what.into(),
        reason: format!("no parameter `{n}`; the model has {}", params_list(options.model)),
    };
    for name in &options.fixed {
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

/// `k_t` [N m/A] and `psi_f` [V s] from every `k_e` estimate (MODEL.md §2).
fn derived(r: &FitResult, n_p: u32) -> Vec<DerivedEstimate> {
    let kt = (1.5f64).sqrt();
    let psi = (2.0f64 / 3.0).sqrt() / f64::from(n_p);
    r.parameters
        .iter()
        .filter(|p| p.name == "k_e")
        .flat_map(|p| {
            [
                DerivedEstimate {
                    name: "k_t".into(),
                    unit: "N m/A".into(),
                    value: kt * p.value,
                    std_error: kt * p.std_error,
                    experiment: p.experiment.clone(),
                },
                DerivedEstimate {
                    name: "psi_f".into(),
                    unit: "V s".into(),
                    value: psi * p.value,
                    std_error: psi * p.std_error,
                    experiment: p.experiment.clone(),
                },
            ]
        })
        .collect()
}
