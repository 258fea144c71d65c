//! The start of a PMSM fit: linear least squares on the voltage equations (thesis 5.2.1),
//! on the applied voltage when the log carries the reference, and with the inverter's
//! dead-time voltage as one more regressor when the fit estimates it (the voltage error is
//! linear in `v_dt`, MODEL.md §4: without that column the regression lends it to `r_s` and
//! the inductances, which can turn them negative).

use super::regression::{Regression, push_with_dead_time};
use crate::error::{Error, Result};
use crate::estimate::linear::StreamedLeastSquares;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::{VoltageInput, driving_voltage};
use crate::pmsm::model::inverter::{InverterModel, dead_time_directions};
use crate::pmsm::model::kind::MotorKind;

/// The least-squares start `(names, θ)` of the logs `views`: the motor's parameters with the cable resistance
/// taken out of `r_s`, and `v_dt` (clamped at 0) when `inverter` is estimated. For a
/// salient motor, a non-positive `r_s`, `l_d` or `l_q` is replaced by the surface-magnet
/// regression's `r_s` or `l_s`.
///
/// # Errors
/// Those of [`applied_voltage`](crate::pmsm::model::interval::applied_voltage), [`StreamedLeastSquares::solve`] and [`dead_time_directions`]; [`Error::Numerical`] when a
/// resistance or inductance comes out non-positive (give a start).
pub(crate) fn least_squares_start(
    views: &[DqView<'_>],
    n_p: u32,
    kind: MotorKind,
    input: VoltageInput,
    cable_resistance: f64,
    inverter: Option<&InverterModel>,
) -> Result<(Vec<String>, Vec<f64>)> {
    crate::pmsm::log::signals::check_pole_pairs(n_p)?;
    let dead_time = inverter.filter(|i| i.known.is_none());
    let regress = |kind: MotorKind| regress(views, n_p, kind, input, dead_time);
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
                    reason: format!(
                        "`{n}` = {v:e} is not positive: check the columns first (d and q, voltage and current, the \
                         speed's sign, unit and frame); only when they are right, give a start value (--start)"
                    ),
                });
            }
            _ => {}
        }
    }
    Ok((names, theta))
}

/// The least-squares `(names, θ)` of `kind` on the applied voltage of `input`, streamed
/// (no regressor matrix is formed); with `dead_time`, each interval's d and q rows gain
/// the column `−Re d_k`, `−Im d_k` (`d_k` the per-unit error of [`dead_time_directions`])
/// and the names `v_dt`.
fn regress(
    views: &[DqView<'_>],
    n_p: u32,
    kind: MotorKind,
    input: VoltageInput,
    dead_time: Option<&InverterModel>,
) -> Result<(Vec<String>, Vec<f64>)> {
    let names: Vec<String> = kind
        .parameter_names()
        .iter()
        .map(|s| s.to_string())
        .chain(dead_time.map(|_| "v_dt".to_string()))
        .collect();
    let mut ls = StreamedLeastSquares::new(names.len());
    for v in views {
        let (u_d, u_q) = driving_voltage(v, n_p, input)?;
        let reg = Regression::new(v, &u_d, &u_q, n_p, kind);
        let cols = reg.cols();
        match dead_time {
            None => {
                reg.for_each(|_, d, q, u| {
                    ls.push(&d[..cols], u[0], 1.0);
                    ls.push(&q[..cols], u[1], 1.0);
                });
            }
            Some(model) => {
                let dirs = dead_time_directions(v, n_p, model)?;
                for (k, dir) in dirs.iter().enumerate().take(reg.intervals()) {
                    let (d, q, u) = reg.rows(k);
                    push_with_dead_time(&mut ls, &d[..], &q[..], [u[0], u[1]], cols, *dir);
                }
            }
        }
    }
    let theta = ls.solve(&names)?.theta;
    Ok((names, theta))
}

/// The start after the user's constraints: the values of `options.fixed_values` put in,
/// and, for a least-squares start (`options.start` is `None`), every other entry outside
/// its `options.bounds` clamped to the nearest bound, with a note in `notes`. `names` are
/// the fitted parameters in model order (`start` has their length).
///
/// # Errors
/// [`Error::InvalidOption`] (option `fixed`) for a fixed value of a parameter the model
/// does not have or that is not finite.
pub(crate) fn user_start(
    mut start: Vec<f64>,
    names: &[&str],
    options: &crate::pmsm::PmsmFitOptions,
    notes: &mut Vec<String>,
) -> Result<Vec<f64>> {
    let index = |name: &str| names.iter().position(|n| *n == name);
    for (name, v) in &options.fixed_values {
        let Some(j) = index(name) else {
            return Err(Error::InvalidOption {
                option: "fixed".into(),
                reason: format!("no parameter `{name}`; the model has {}", names.join(", ")),
            });
        };
        if !v.is_finite() {
            return Err(Error::InvalidOption {
                option: "fixed".into(),
                reason: format!("`{name}` = {v}: a fixed value must be finite"),
            });
        }
        start[j] = *v;
    }
    if options.start.is_some() {
        return Ok(start);
    }
    for (name, lo, hi) in &options.bounds {
        let Some(j) = index(name) else { continue };
        if options.fixed_values.iter().any(|(n, _)| n == name)
            || lo.partial_cmp(hi) != Some(std::cmp::Ordering::Less)
        {
            continue;
        }
        let s = start[j];
        let clamped = s.clamp(*lo, *hi);
        if clamped != s {
            notes.push(format!(
                "the least-squares start of {name}, {s:.7}, lies outside its bounds [{lo}, {hi}]: started at \
                 {clamped} (the nearest bound; SI units)"
            ));
            start[j] = clamped;
        }
    }
    Ok(start)
}
