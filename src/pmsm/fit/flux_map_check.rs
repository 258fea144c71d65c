//! What a user reads off a fitted flux map, checked against the map itself (issue 43): the
//! no-load flux `ψ_d(0, 0)` and the incremental inductances at the printed operating points,
//! with 95 % intervals, from the model that predicts the map's held-out points best: the
//! saturation model (Hinkkanen et al. 2017) or, where the map asks for more, smoothing
//! splines of `ψ_d` and `ψ_q` over the current plane ([`SplineSurface`]). Each printed
//! figure is compared with the map's own value (its point at zero current, its central
//! differences on the grid), and a miss beyond the stated accuracy makes the fit untrusted.
//!
//! Why: on the measured Baldor map the saturation model's flux at zero current is 0.498 V s
//! against the map's 0.444 V s (+12 %) with ψ_f ± 0.6 %, and exit 0; the model family is too
//! stiff for real maps at low current, and its residual alone could not say so.
//!
//! Held-out errors: both models by the same 5-fold cross-validation (the saturation model
//! refitted at its chosen exponents, the splines at their knot intervals, without each
//! fifth of the points, the folds scattered over the map by a hash of the point's index);
//! the splines' knot intervals themselves chosen by leave-one-out.

use super::flux_map_grid::Grid;
use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::spline::SplineSurface;
use crate::estimate::{FitResult, Warning};
use crate::pmsm::model::saturation::{Saturation, SaturationExponents};
use serde::{Deserialize, Serialize};

/// The no-load flux must lie within this fraction of the map's `ψ_d(0, 0)`.
pub const NO_LOAD_WITHIN: f64 = 0.01;

/// The printed incremental inductances `L_dd`, `L_qq` must lie within this fraction of the
/// map's central differences.
pub const INDUCTANCE_WITHIN: f64 = 0.10;

/// Folds of the saturation model's cross-validation.
pub const FOLDS: usize = 5;

/// A figure with its standard error \[its unit\].
pub type Figure = (f64, f64);

/// The model whose figures the report gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MapModel {
    /// The saturation model (its coefficients are the fit's).
    Saturation,
    /// Regression splines (least-squares cubic B-splines) of `ψ_d` and `ψ_q`.
    Spline,
}

/// One printed operating point: the chosen model's incremental inductances \[H\] with
/// standard errors, and the map's central differences there (`None` off the grid).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PointCheck {
    /// `[i_d, i_q]` \[A\].
    pub i: [f64; 2],
    /// `∂ψ_d/∂i_d`, `∂ψ_q/∂i_q`, `∂ψ_d/∂i_q` of the chosen model.
    pub model: [Figure; 3],
    /// The same from the map's grid (central differences, one-sided at its edges).
    pub map: Option<[f64; 3]>,
    /// The chosen model's differences on the same stencil (what the check compares with
    /// the map's: a tangent and a secant over 2 grid steps differ where the flux curves).
    pub model_stencil: Option<[f64; 3]>,
}

/// The map checked against its chosen model.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MapCheck {
    /// The model chosen by held-out error.
    pub chosen: MapModel,
    /// RMS held-out flux error (5-fold) of the saturation model and of the splines \[V s\]
    /// (∞ when a fold's fit failed).
    pub held_out_rms: [f64; 2],
    /// The splines (ψ_d, ψ_q), when they could be fitted.
    pub splines: Option<[SplineSurface; 2]>,
    /// The no-load flux `ψ_d(0, 0)` of the chosen model and its error (standard error and
    /// held-out error in quadrature) \[V s\].
    pub no_load: Figure,
    /// The map's own `ψ_d` at zero current (`None` without a point there) \[V s\].
    pub no_load_map: Option<f64>,
    /// The printed operating points.
    pub points: Vec<PointCheck>,
    /// Untrusted warnings: `no_load_flux`, `inductance_mismatch`.
    pub warnings: Vec<Warning>,
}

/// `g(θ)` and its standard error by the delta method, the gradient by central differences
/// (step 1e-6 of each coefficient's size) and the covariance from the fit's standard errors
/// and correlation.
fn delta(result: &FitResult, g: &dyn Fn(&[f64]) -> Option<f64>) -> Option<Figure> {
    let theta: Vec<f64> = result.parameters.iter().map(|p| p.value).collect();
    let v = g(&theta)?;
    let n = theta.len();
    let mut grad = vec![0.0; n];
    for (j, gj) in grad.iter_mut().enumerate() {
        let p = &result.parameters[j];
        if p.fixed || !p.std_error.is_finite() || p.std_error == 0.0 {
            continue;
        }
        let h = 1e-6 * theta[j].abs().max(p.std_error);
        let (mut up, mut down) = (theta.clone(), theta.clone());
        up[j] += h;
        down[j] -= h;
        *gj = (g(&up)? - g(&down)?) / (2.0 * h);
    }
    let name = |j: usize| result.parameters[j].name.as_str();
    let corr = |a: usize, b: usize| {
        let (ia, ib) = (
            result.correlation_names.iter().position(|c| c == name(a)),
            result.correlation_names.iter().position(|c| c == name(b)),
        );
        match (ia, ib) {
            (Some(x), Some(y)) => result.correlation[x][y],
            _ => f64::from(u8::from(a == b)),
        }
    };
    let se = |j: usize| if grad[j] == 0.0 { 0.0 } else { result.parameters[j].std_error };
    let var: f64 = (0..n)
        .flat_map(|a| (0..n).map(move |b| (a, b)))
        .map(|(a, b)| grad[a] * grad[b] * se(a) * se(b) * corr(a, b))
        .sum();
    Some((v, var.max(0.0).sqrt()))
}

/// The fold of point `k`: a multiplicative hash, so that no fold is a whole row or column
/// of a map's grid.
fn fold(k: usize) -> usize {
    ((k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32) as usize % FOLDS
}

/// The saturation model's rms flux error over the points each fold leaves out, refitted at
/// exponents `e` from `result`'s estimate without them \[V s\] (`None` when a fold fails).
fn cross_validated(map: &Experiment, e: SaturationExponents, result: &FitResult) -> Option<f64> {
    let theta: Vec<f64> = result.parameters.iter().map(|p| p.value).collect();
    let (mut sse, mut count) = (0.0, 0usize);
    for f in 0..FOLDS {
        let keep = |k: &usize| fold(*k) != f;
        let r = super::flux_map_regions::refit_where(map, e, &theta, format!("{}#{f}", map.name()), &|k| {
            keep(&k)
        })?
        .ok()?;
        let values: Vec<f64> = r.parameters.iter().map(|p| p.value).collect();
        let m = Saturation::from_theta(&values, e);
        let col = |n: &str| map.channel(n).ok();
        let (i_d, i_q, psi_d, psi_q) = (col("i_d")?, col("i_q")?, col("psi_d")?, col("psi_q")?);
        for k in (0..map.len()).filter(|k| !keep(k)) {
            let psi = m.flux([i_d[k], i_q[k]]).ok()?;
            sse += (psi[0] - psi_d[k]).powi(2) + (psi[1] - psi_q[k]).powi(2);
            count += 2;
        }
    }
    Some((sse / count.max(1) as f64).sqrt())
}

/// The map's check (module documentation): `e` and `result` the saturation model's fit,
/// `at` the operating points to print (snapped to the map's grid where it has one).
///
/// # Errors
/// [`crate::Error::MissingChannel`] for a map without `i_d, i_q, psi_d, psi_q`.
pub(crate) fn check(
    map: &Experiment,
    e: SaturationExponents,
    result: &FitResult,
    at: &[[f64; 2]],
) -> Result<MapCheck> {
    let [i_d, i_q, psi_d, psi_q] = ["i_d", "i_q", "psi_d", "psi_q"].map(|c| map.channel(c));
    let (i_d, i_q, psi_d, psi_q) = (i_d?, i_q?, psi_d?, psi_q?);
    let i: Vec<[f64; 2]> = i_d.iter().zip(i_q).map(|(d, q)| [*d, *q]).collect();
    let psi: Vec<[f64; 2]> = psi_d.iter().zip(psi_q).map(|(d, q)| [*d, *q]).collect();
    let grid = Grid::of(&i, &psi);
    let splines = SplineSurface::fit_chosen(&i, psi_d)
        .and_then(|d| Ok([d, SplineSurface::fit_chosen(&i, psi_q)?]))
        .ok();
    let spline_rms = splines
        .as_ref()
        .and_then(|[d, q]| {
            let cv = |s: &SplineSurface, z: &[f64]| s.cross_validated(&i, z, FOLDS, &fold);
            Some(cv(d, psi_d)?.hypot(cv(q, psi_q)?) / 2f64.sqrt())
        })
        .unwrap_or(f64::INFINITY);
    let model_rms = cross_validated(map, e, result).unwrap_or(f64::INFINITY);
    let chosen = if spline_rms < model_rms { MapModel::Spline } else { MapModel::Saturation };
    let flux =
        |theta: &[f64], p: [f64; 2], k: usize| Saturation::from_theta(theta, e).flux(p).ok().map(|f| f[k]);
    let incremental = |theta: &[f64], p: [f64; 2], which: usize| {
        Saturation::from_theta(theta, e).inductances(p).ok().map(|l| [l.l_dd, l.l_qq, l.l_dq][which])
    };
    let nan = (f64::NAN, f64::NAN);
    // The no-load flux's error: its standard error and the model's held-out error at a
    // point of the map in quadrature (a smooth model's bias at a kink of the map is in the
    // latter, not the former).
    let no_load = match (&splines, chosen) {
        (Some([d, _]), MapModel::Spline) => {
            let (v, se) = d.value([0.0, 0.0]);
            (v, se.hypot(d.held_out_rms))
        }
        _ => delta(result, &|t| flux(t, [0.0, 0.0], 0)).map_or(nan, |(v, se)| (v, se.hypot(model_rms))),
    };
    let fitted: Vec<f64> = result.parameters.iter().map(|p| p.value).collect();
    let saturation = Saturation::from_theta(&fitted, e);
    let model_flux = |p: [f64; 2]| match (&splines, chosen) {
        (Some([d, q]), MapModel::Spline) => Some([d.value(p).0, q.value(p).0]),
        _ => saturation.flux(p).ok(),
    };
    let points: Vec<PointCheck> = at
        .iter()
        .map(|&p| {
            let p = match &grid {
                // `+ 0.0` writes a grid's −0 as 0.
                Some(g) => [Grid::nearest(&g.d, p[0]) + 0.0, Grid::nearest(&g.q, p[1]) + 0.0],
                None => p,
            };
            let model = match (&splines, chosen) {
                (Some([d, q]), MapModel::Spline) => [d.slope_x(p), q.slope_y(p), d.slope_y(p)],
                _ => [0, 1, 2].map(|w| delta(result, &|t| incremental(t, p, w)).unwrap_or(nan)),
            };
            let map = grid.as_ref().and_then(|g| g.differences(p, &|x| g.psi(x)));
            let model_stencil = grid.as_ref().and_then(|g| g.differences(p, &model_flux));
            PointCheck { i: p, model, map, model_stencil }
        })
        .collect();
    let no_load_map = grid.as_ref().and_then(|g| g.psi([0.0, 0.0])).map(|p| p[0]);
    let warnings = verdict(no_load, no_load_map, &points);
    Ok(MapCheck {
        chosen,
        held_out_rms: [model_rms, spline_rms],
        splines,
        no_load,
        no_load_map,
        points,
        warnings,
    })
}

/// The untrusted warnings of a check: the no-load flux more than [`NO_LOAD_WITHIN`] off the
/// map's or outside its 95 % interval; an `L_dd` or `L_qq` of the model on the map's stencil
/// more than [`INDUCTANCE_WITHIN`] off the map's central difference at a printed point.
fn verdict(no_load: Figure, map: Option<f64>, points: &[PointCheck]) -> Vec<Warning> {
    let mut out = Vec::new();
    if let Some(m) = map {
        let off = no_load.0 / m - 1.0;
        let within = off.abs() <= NO_LOAD_WITHIN && (no_load.0 - m).abs() <= 1.96 * no_load.1;
        if !within {
            out.push(Warning::untrusted(
                "no_load_flux",
                format!(
                    "the model's no-load flux ψ_d(0, 0) = {:.4} ± {:.4} V s (95 %) misses the map's {m:.4} V s by \
                     {:+.2} %: the model does not describe the map at low current",
                    no_load.0,
                    1.96 * no_load.1,
                    100.0 * off
                ),
            ));
        }
    }
    let misses: Vec<String> = points
        .iter()
        .filter_map(|p| {
            let (m, own) = (p.map?, p.model_stencil?);
            let bad: Vec<String> = [("L_dd", 0), ("L_qq", 1)]
                .into_iter()
                .filter(|(_, k)| {
                    (own[*k] / m[*k] - 1.0).abs().partial_cmp(&INDUCTANCE_WITHIN)
                        != Some(std::cmp::Ordering::Less)
                })
                .map(|(n, k)| format!("{n} {:.3} mH vs the map's {:.3} mH", 1e3 * own[k], 1e3 * m[k]))
                .collect();
            (!bad.is_empty()).then(|| format!("at ({:.1}, {:.1}) A: {}", p.i[0], p.i[1], bad.join(", ")))
        })
        .collect();
    if !misses.is_empty() {
        out.push(Warning::untrusted(
            "inductance_mismatch",
            format!(
                "the model's incremental inductances (its differences on the map's grid) miss the map's central \
                 differences by more than {:.0} %: {}",
                100.0 * INDUCTANCE_WITHIN,
                misses.join("; ")
            ),
        ));
    }
    out
}

impl std::fmt::Display for MapCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [model, spline] = self.held_out_rms;
        let knots = self.splines.as_ref().map_or(String::new(), |[d, q]| {
            format!(" (knot intervals by leave-one-out: ψ_d {}×{}, ψ_q {}×{})", d.x.1, d.y.1, q.x.1, q.y.1)
        });
        writeln!(
            f,
            "\nheld-out flux error (rms, the same {FOLDS} folds): saturation model {model:.3e} V s, regression splines \
             {spline:.3e} V s{knots}: the figures below are the {}",
            match self.chosen {
                MapModel::Saturation => "saturation model's",
                MapModel::Spline => "regression splines'",
            }
        )?;
        let ci = |x: Figure| format!("{:.4} ± {:.4}", x.0, 1.96 * x.1);
        let map = self.no_load_map.map_or("no point at zero current".into(), |m| {
            format!("the map's {m:.4} V s ({:+.2} %)", 100.0 * (self.no_load.0 / m - 1.0))
        });
        writeln!(
            f,
            "no-load flux ψ_d(0, 0) = {} V s (95 %: standard error and held-out error in quadrature); {map}",
            ci(self.no_load)
        )?;
        writeln!(
            f,
            "incremental inductances [mH] (95 %) and the map's central differences (the check compares the model's \
             on the same grid):\n{:>8} {:>8} {:>18} {:>8} {:>18} {:>8} {:>18} {:>8}",
            "i_d [A]", "i_q [A]", "L_dd", "map", "L_qq", "map", "L_dq", "map"
        )?;
        let mh = |x: Figure| format!("{:.3} ± {:.3}", 1e3 * x.0, 1.96e3 * x.1);
        let m = |p: &PointCheck, k: usize| p.map.map_or("-".into(), |v| format!("{:.3}", 1e3 * v[k]));
        for p in &self.points {
            writeln!(
                f,
                "{:>8.2} {:>8.2} {:>18} {:>8} {:>18} {:>8} {:>18} {:>8}",
                p.i[0],
                p.i[1],
                mh(p.model[0]),
                m(p, 0),
                mh(p.model[1]),
                m(p, 1),
                mh(p.model[2]),
                m(p, 2)
            )?;
        }
        for w in &self.warnings {
            writeln!(f, "WARNING [{}]: {}", w.code, w.message)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Baldor map's saturation model (ψ_f 0.498 V s against the map's 0.444 V s) fails
    /// the no-load check; a figure within 1 % whose interval covers the map's passes; an
    /// inductance off by 20 % on the map's stencil fails.
    #[test]
    fn the_verdict_names_what_misses_the_map() {
        let point = |own: f64| PointCheck {
            i: [0.0, 0.0],
            model: [(own, 1e-4), (0.14, 1e-4), (0.0, 1e-4)],
            map: Some([0.025, 0.14, 0.0]),
            model_stencil: Some([own, 0.14, 0.0]),
        };
        let codes = |w: Vec<Warning>| w.into_iter().map(|w| w.code).collect::<Vec<_>>();
        assert_eq!(codes(verdict((0.498, 0.0015), Some(0.444), &[point(0.025)])), ["no_load_flux"]);
        assert!(verdict((0.4457, 0.001), Some(0.4441), &[point(0.026)]).is_empty());
        assert_eq!(codes(verdict((0.4441, 0.001), Some(0.4441), &[point(0.030)])), ["inductance_mismatch"]);
    }
}
