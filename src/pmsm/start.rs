//! The start of a PMSM fit: linear least squares on the voltage equations (thesis 5.2.1),
//! on the applied voltage when the log carries the reference, and with the inverter's
//! dead-time voltage as one more regressor when the fit estimates it (the voltage error is
//! linear in `v_dt`, MODEL.md §4: without that column the regression lends it to `r_s` and
//! the inductances, which can turn them negative).

use super::interval::{VoltageInput, applied_experiment};
use super::inverter::{InverterModel, dead_time_directions};
use super::kind::MotorKind;
use super::linear::{least_squares, regressors};
use super::signals::DqView;
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::linear::solve_weighted;

/// The least-squares start `(names, θ)`: the motor's parameters with the cable resistance
/// taken out of `r_s`, and `v_dt` (clamped at 0) when `inverter` is estimated. For a
/// salient motor, a non-positive `r_s`, `l_d` or `l_q` is replaced by the surface-magnet
/// regression's `r_s` or `l_s`.
///
/// # Errors
/// Those of [`least_squares`] and [`dead_time_directions`]; [`Error::Numerical`] when a
/// resistance or inductance comes out non-positive (give a start).
pub(crate) fn least_squares_start(
    experiments: &[Experiment],
    n_p: u32,
    kind: MotorKind,
    input: VoltageInput,
    cable_resistance: f64,
    inverter: Option<&InverterModel>,
) -> Result<(Vec<String>, Vec<f64>)> {
    let applied = applied_experiments(experiments, n_p, input)?;
    let data = applied.as_deref().unwrap_or(experiments);
    let regress = |kind: MotorKind| match inverter.filter(|i| i.known.is_none()) {
        Some(model) => with_dead_time(data, n_p, kind, model),
        None => least_squares(data, n_p, kind).map(|ls| (ls.names, ls.theta)),
    };
    let (names, mut theta) = regress(kind)?;
    // A salient regression with little d-axis excitation can give a non-positive `r_s` or
    // inductance: start those from the surface-magnet regression (`l_s` for both).
    if kind == MotorKind::Ipm && theta[..3].iter().any(|v| *v <= 0.0) {
        let (_, spm) = regress(MotorKind::Spm)?;
        for (j, v) in theta.iter_mut().take(3).enumerate() {
            if *v <= 0.0 {
                *v = spm[j.min(1)];
            }
        }
    }
    // The regression sees the whole series resistance; the model adds the cable.
    theta[0] -= cable_resistance;
    for (n, v) in names.iter().zip(theta.iter_mut()) {
        match n.as_str() {
            "k_e" => {}
            "v_dt" => *v = v.max(0.0),
            _ if *v <= 0.0 => {
                return Err(Error::Numerical {
                    context: "least-squares start".into(),
                    reason: format!("`{n}` = {v:e} is not positive; give a start value (--start)"),
                });
            }
            _ => {}
        }
    }
    Ok((names, theta))
}

/// Least squares with the dead-time voltage: each interval's d and q rows gain the column
/// `−Re d_k`, `−Im d_k`, `d_k` the per-unit error of [`dead_time_directions`].
fn with_dead_time(
    experiments: &[Experiment],
    n_p: u32,
    kind: MotorKind,
    model: &InverterModel,
) -> Result<(Vec<String>, Vec<f64>)> {
    let names: Vec<String> =
        kind.parameter_names().iter().map(|s| s.to_string()).chain(["v_dt".into()]).collect();
    let cols = names.len() - 1;
    let (mut phi, mut y) = (Vec::new(), Vec::new());
    for e in experiments {
        let v = DqView::try_new(e)?;
        let (p, u) = regressors(&v, n_p, kind)?;
        let dirs = dead_time_directions(&v, n_p, model)?;
        for (k, d) in dirs.iter().enumerate() {
            phi.extend_from_slice(&p[2 * k * cols..(2 * k + 1) * cols]);
            phi.push(-d.re);
            phi.extend_from_slice(&p[(2 * k + 1) * cols..(2 * k + 2) * cols]);
            phi.push(-d.im);
        }
        y.extend(u);
    }
    let weights = vec![1.0; y.len()];
    let theta = solve_weighted(&names, &phi, &y, &weights)?.theta;
    Ok((names, theta))
}

/// With a reference input, the experiments with their `ud, uq` replaced by the applied
/// period-mean voltage; `None` for the terminal input.
fn applied_experiments(
    experiments: &[Experiment],
    n_p: u32,
    input: VoltageInput,
) -> Result<Option<Vec<Experiment>>> {
    if input == VoltageInput::Terminal {
        return Ok(None);
    }
    experiments.iter().map(|e| applied_experiment(e, n_p, input)).collect::<Result<Vec<_>>>().map(Some)
}
