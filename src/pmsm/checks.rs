//! Residual checks after a PMSM fit that point at what the model leaves out (MODEL.md §4):
//! the voltage-equation residual at the estimate, `r = u − Φ θ̂` (d and q rows per interval,
//! the regressors of the least-squares start), correlated with
//! - the inverter's error direction per unit `v_dt` (sign of the phase currents): a
//!   dead-time voltage the model does not have;
//! - the change of the voltage from one sample to the next: a voltage that acts one sample
//!   later than the model assumes (a reference logged as if it were the terminal voltage).

use super::interval::{VoltageInput, applied_experiment};
use super::inverter::{InverterModel, dead_time_directions};
use super::kind::MotorKind;
use super::linear::regressors;
use super::signals::DqView;
use crate::data::Experiment;
use crate::estimate::Warning;
use crate::estimate::linear::solve_weighted;

/// |correlation| above which a check speaks.
pub const THRESHOLD: f64 = 0.3;

/// Pearson correlation of two equally long series (0 for a constant one).
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa > 0.0 && sbb > 0.0 { sab / (saa * sbb).sqrt() } else { 0.0 }
}

/// Fraction of the residual sum of squares of the least-squares regression `y ~ Φ` that an
/// extra column `extra` removes: `1 − RSS([Φ, extra]) / RSS(Φ)` (0 when either regression
/// fails).
fn explained_beyond(phi: &[f64], y: &[f64], cols: usize, extra: &[f64]) -> f64 {
    let rss = |phi: &[f64], cols: usize| -> Option<f64> {
        let names: Vec<String> = (0..cols).map(|j| format!("c{j}")).collect();
        let sol = solve_weighted(&names, phi, y, &vec![1.0; y.len()]).ok()?;
        Some(sol.e2)
    };
    let with: Vec<f64> =
        (0..y.len()).flat_map(|i| phi[i * cols..(i + 1) * cols].iter().copied().chain([extra[i]])).collect();
    match (rss(phi, cols), rss(&with, cols + 1)) {
        (Some(a), Some(b)) if a > 0.0 => 1.0 - b / a,
        _ => 0.0,
    }
}

/// The checks' advice for a fit of `kind` at `theta` (model order, without nuisance
/// parameters) on `experiments` driven by `input`; `inverter` says whether the fit modelled
/// the inverter. Logs the checks cannot read (no angle for the phase currents) are passed
/// over; each warning (untrusted: the model lacks what the data show; codes `dead_time`,
/// `voltage_late`) names the log and the correlation.
pub fn advice(
    experiments: &[Experiment],
    n_p: u32,
    kind: MotorKind,
    input: VoltageInput,
    theta: &[f64],
    inverter: bool,
) -> Vec<Warning> {
    let mut out = Vec::new();
    for e in experiments {
        let Ok(v) = DqView::try_new(e) else { continue };
        let Ok(applied) = applied_experiment(e, n_p, input) else { continue };
        let Ok(av) = DqView::try_new(&applied) else { continue };
        let Ok((phi, y)) = regressors(&av, n_p, kind) else { continue };
        let cols = theta.len();
        let r: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(i, yi)| yi - (0..cols).map(|j| phi[i * cols + j] * theta[j]).sum::<f64>())
            .collect();
        if !inverter && let Ok(dirs) = dead_time_directions(&v, n_p, &InverterModel::default()) {
            // The resistance absorbs much of a dead-time voltage (both oppose the current), so
            // ask how much of the regression's residual the sign of the phase currents
            // explains beyond the motor's own regressors.
            let d: Vec<f64> = dirs.iter().flat_map(|c| [-c.re, -c.im]).collect();
            let gain = explained_beyond(&phi, &y, cols, &d);
            if gain > THRESHOLD {
                out.push(Warning::untrusted("dead_time", format!(
                    "`{}`: the sign of the phase currents explains {:.0} % of the voltage residual the motor's \
                     parameters leave: an inverter dead-time voltage the model does not have (it biases r_s); fit \
                     the reference voltage with the inverter model (--voltage reference --dead-time estimate), or \
                     use the measured terminal voltage",
                    e.name(),
                    100.0 * gain
                )));
            }
        }
        // Interval k's voltage change u[k] − u[k−1], rows d, q as in the residual.
        let Ok((ud, uq)) = av.terminal_voltage() else { continue };
        let du: Vec<f64> = (0..ud.len() - 1)
            .flat_map(|k| if k == 0 { [0.0, 0.0] } else { [ud[k] - ud[k - 1], uq[k] - uq[k - 1]] })
            .collect();
        let c = correlation(&r, &du);
        if c.abs() > THRESHOLD {
            out.push(Warning::untrusted("voltage_late", format!(
                "`{}`: the voltage residual follows the voltage's change from the sample before (correlation \
                 {c:+.2}): the voltage acts later than the model assumes, as a controller's reference does \
                 (--voltage reference --delay estimate)",
                e.name()
            )));
        }
    }
    out
}
