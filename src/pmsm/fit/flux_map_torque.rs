//! A measured torque beside a flux map: the torque the fitted model's flux gives, `T_e =
//! 1.5 n_p (ψ_d i_q − ψ_q i_d)` (MODEL.md §2, amplitude-invariant dq), compared with the
//! torque measured at the map's points, and the same from the map's own flux. What the
//! flux cannot show (friction and iron-loss torque, the torque sensor's offset, a wrong
//! pole-pair number) is in the second; what the model misses of the flux, in the first.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::fit::flux_map::FluxMapFit;
use crate::pmsm::fit::flux_map_check::MapModel;
use crate::pmsm::model::saturation::flux_torque as torque;
use serde::{Deserialize, Serialize};

/// The model's and the map's torque against the measured one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TorqueCheck {
    /// Pole pairs the torque was computed with.
    pub n_p: u32,
    /// The model whose flux gave the model's torque (the one the report's figures are).
    pub model: MapModel,
    /// Points with a measured torque (the others are left out).
    pub points: usize,
    /// The measured torque's range `max − min` \[N m\].
    pub range: f64,
    /// RMS of `T_model − T_measured` \[N m\].
    pub rms_model: f64,
    /// Mean of `T_model − T_measured` \[N m\] (an offset: friction, a sensor's zero).
    pub mean_model: f64,
    /// Largest `|T_model − T_measured|` \[N m\] and the current `[i_d, i_q]` \[A\] there.
    pub max_model: (f64, [f64; 2]),
    /// RMS of `T_map − T_measured` \[N m\], the torque of the map's own flux.
    pub rms_map: f64,
}

/// The [`TorqueCheck`] of the measured torque `measured` \[N m\] (one per point of `map`,
/// NaN where none was measured) at `n_p` pole pairs, the model's flux that of `fit`'s
/// chosen model (the regression splines where the map check chose them, else the
/// saturation model).
///
/// # Errors
/// [`Error::InvalidOption`] (`torque`) when `measured` does not have one value per point or
/// no point has a finite one; those of the saturation model's flux.
pub fn torque_check(map: &Experiment, fit: &FluxMapFit, measured: &[f64], n_p: u32) -> Result<TorqueCheck> {
    let [i_d, i_q, psi_d, psi_q] = ["i_d", "i_q", "psi_d", "psi_q"].map(|c| map.channel(c));
    let (i_d, i_q, psi_d, psi_q) = (i_d?, i_q?, psi_d?, psi_q?);
    let invalid = |reason: String| Error::InvalidOption { option: "torque".into(), reason };
    if measured.len() != map.len() {
        return Err(invalid(format!("{} torque values for {} points", measured.len(), map.len())));
    }
    let splines =
        fit.check.as_ref().filter(|c| c.chosen == MapModel::Spline).and_then(|c| c.splines.as_ref());
    let model = if splines.is_some() { MapModel::Spline } else { MapModel::Saturation };
    let model_flux = |i: [f64; 2]| -> Result<[f64; 2]> {
        match splines {
            Some([d, q]) => Ok([d.value(i).0, q.value(i).0]),
            None => fit.model.flux(i),
        }
    };
    let (mut n, mut sum, mut sum_sq, mut sum_sq_map) = (0usize, 0.0, 0.0, 0.0);
    let (mut lo, mut hi, mut max_model) = (f64::INFINITY, f64::NEG_INFINITY, (0.0, [0.0; 2]));
    for k in (0..map.len()).filter(|&k| measured[k].is_finite()) {
        let i = [i_d[k], i_q[k]];
        let e = torque(n_p, i, model_flux(i)?) - measured[k];
        let e_map = torque(n_p, i, [psi_d[k], psi_q[k]]) - measured[k];
        n += 1;
        sum += e;
        sum_sq += e * e;
        sum_sq_map += e_map * e_map;
        (lo, hi) = (lo.min(measured[k]), hi.max(measured[k]));
        if e.abs() > max_model.0 {
            max_model = (e.abs(), i);
        }
    }
    if n == 0 {
        return Err(invalid("no point of the map has a measured torque".into()));
    }
    let count = n as f64;
    Ok(TorqueCheck {
        n_p,
        model,
        points: n,
        range: hi - lo,
        rms_model: (sum_sq / count).sqrt(),
        mean_model: sum / count,
        max_model,
        rms_map: (sum_sq_map / count).sqrt(),
    })
}

impl std::fmt::Display for TorqueCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let share = |x: f64| if self.range > 0.0 { 100.0 * x / self.range } else { f64::NAN };
        let model = match self.model {
            MapModel::Spline => "the regression splines'",
            MapModel::Saturation => "the saturation model's",
        };
        writeln!(
            f,
            "measured torque at {} points (range {:.4} N m), against 1.5 n_p (ψ_d i_q − ψ_q i_d) with n_p = {}: {model} \
             flux gives rms {:.4e} N m ({:.2} % of the range; mean {:+.4e} N m, largest {:.4e} N m at i = ({:.1}, \
             {:.1}) A); the map's own flux rms {:.4e} N m ({:.2} %: the torque the flux does not carry, such as \
             friction, iron loss or the sensor's offset, or another n_p)",
            self.points,
            self.range,
            self.n_p,
            self.rms_model,
            share(self.rms_model),
            self.mean_model,
            self.max_model.0,
            self.max_model.1[0],
            self.max_model.1[1],
            self.rms_map,
            share(self.rms_map)
        )
    }
}
