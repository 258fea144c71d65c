//! From the parsed columns of a log to a validated [`Experiment`]: units, frames and
//! scaling converted, dq derived from phases if asked, errors in the configured names.

use super::{ColumnNames, CsvOptions, DqSource};
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::log::signals::{DqSignals, DqView};
use crate::pmsm::log::transform::{currents_to_dq, stator_held_voltages_to_dq};

/// Converts units, derives dq from phases if asked, and validates. `cols` are in the
/// order of [`read_log`](super::read_log)'s request, the time column already in seconds.
pub(super) fn build(
    name: String,
    cols: Vec<Option<Vec<f64>>>,
    n_p: u32,
    options: &CsvOptions,
) -> Result<Experiment> {
    let phases = options.source == DqSource::Phases;
    let mut cols = cols.into_iter();
    let mut next = || cols.next().flatten();
    let t = next().unwrap_or_default();
    let main: Vec<Vec<f64>> = (0..if phases { 7 } else { 4 }).map(|_| next().unwrap_or_default()).collect();
    let mut w_m = next().unwrap_or_default();
    let mut theta_m = if phases { main.get(6).cloned() } else { next() };
    let mut u_d_ref = next();
    let mut u_q_ref = next();
    let extra: Vec<(String, Vec<f64>)> = options
        .columns
        .extra
        .iter()
        .zip(cols.by_ref())
        .filter_map(|(name, c)| c.map(|c| (name.clone(), c)))
        .collect();

    let (speed, angle) = (options.speed_factor(n_p), options.angle_factor(n_p));
    let (i_scale, u_scale) = (options.current_scale.factor(), options.voltage_scale.factor());
    scale_in_place(&mut w_m, speed);
    if let Some(v) = theta_m.as_mut() {
        scale_in_place(v, angle);
    }
    for v in [u_d_ref.as_mut(), u_q_ref.as_mut()].into_iter().flatten() {
        scale_in_place(v, u_scale);
    }

    let (u_d, u_q, i_d, i_q) = match <[Vec<f64>; 4]>::try_from(main) {
        Ok([mut u_d, mut u_q, mut i_d, mut i_q]) => {
            scale_in_place(&mut u_d, u_scale);
            scale_in_place(&mut u_q, u_scale);
            scale_in_place(&mut i_d, i_scale);
            scale_in_place(&mut i_q, i_scale);
            (u_d, u_q, i_d, i_q)
        }
        Err(main) => {
            let mut ph: Vec<Vec<f64>> = main.into_iter().take(6).collect();
            for (k, v) in ph.iter_mut().enumerate() {
                scale_in_place(v, if k < 3 { i_scale } else { u_scale });
            }
            let th = theta_m.as_deref().unwrap_or_default();
            // The transforms mix columns and neighbouring rows, so a NaN would surface
            // under a dq name: report the raw column instead.
            let c = &options.columns;
            let names = [&c.i_a, &c.i_b, &c.i_c, &c.u_a, &c.u_b, &c.u_c, &c.theta_m, &c.w_m];
            let cols = ph.iter().map(Vec::as_slice).chain([th, &w_m[..]]);
            for (col, v) in names.into_iter().zip(cols) {
                if let Some((row, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                    return Err(Error::NonFinite { column: col.clone(), row, value });
                }
            }
            let h = mean_step(&t);
            let [i_a, i_b, i_c, u_a, u_b, u_c] = &ph[..] else {
                return Err(Error::Numerical {
                    context: "phase columns".into(),
                    reason: "six expected".into(),
                });
            };
            let (i_d, i_q) = currents_to_dq(i_a, i_b, i_c, th, n_p)?;
            let (u_d, u_q) = stator_held_voltages_to_dq(u_a, u_b, u_c, th, &w_m, h, n_p)?;
            (u_d, u_q, i_d, i_q)
        }
    };
    let signals = DqSignals { u_d, u_q, i_d, i_q, w_m, theta_m, u_d_ref, u_q_ref };
    let mut channels = signals.into_channels();
    channels.extend(extra.into_iter().map(|(name, c)| crate::data::Channel::new(&name, "", c)));
    let e = Experiment::try_from_time(name, "t", &t, channels)?;
    DqView::try_new(&e)?;
    Ok(e)
}

fn scale_in_place(v: &mut [f64], f: f64) {
    if f != 1.0 {
        v.iter_mut().for_each(|x| *x *= f);
    }
}

/// `(t[N−1] − t[0])/(N − 1)`, or NaN below two samples (validation then rejects the log).
fn mean_step(t: &[f64]) -> f64 {
    match t {
        [first, .., last] => (last - first) / (t.len() - 1) as f64,
        _ => f64::NAN,
    }
}

/// Replaces the library's signal names in validation errors by the configured header names,
/// and counts their rows from the file's first data row (`offset` rows before the part built).
pub(super) fn rename_columns(e: Error, c: &ColumnNames, offset: usize) -> Error {
    let map = |col: String| -> String {
        let configured = match col.as_str() {
            "t" => &c.t,
            "ud" => &c.u_d,
            "uq" => &c.u_q,
            "id" => &c.i_d,
            "iq" => &c.i_q,
            "w_m" => &c.w_m,
            "theta_m" => &c.theta_m,
            "ud_ref" => &c.u_d_ref,
            "uq_ref" => &c.u_q_ref,
            _ => return col,
        };
        configured.clone()
    };
    match e {
        Error::NonFinite { column, row, value } => {
            Error::NonFinite { column: map(column), row: row + offset, value }
        }
        Error::NonUniformTime { column, row, dt, expected, tolerance, gap } => {
            Error::NonUniformTime { column: map(column), row: row + offset, dt, expected, tolerance, gap }
        }
        other => other,
    }
}
