//! Fitting the saturation model to a measured flux map: a linear least-squares start in
//! the current (the model is linear in its coefficients given the flux), the exponents
//! chosen from small integers, then the prediction-error fit in the flux.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{FitResult, PemOptions, fit};
use crate::pmsm::fit::flux_map_check::{MapCheck, check};
use crate::pmsm::fit::flux_map_regions::{RegionCheck, check_or_note as regions};
use crate::pmsm::fit::report::estimate_table;
use crate::pmsm::model::flux_map::FluxMapModel;
use crate::pmsm::model::saturation::{Inductances, Saturation, SaturationExponents};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// How a flux map is fitted.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FluxMapOptions {
    /// The exponents `(S, T, U, V)`; `None` chooses them: every `S, T ∈ 1..=9`,
    /// `U, V ∈ 0..=2` is fitted by linear least squares in the current, and the
    /// [`FLUX_MAP_REFINED`] best are refined in the flux; the smallest flux residual wins.
    pub exponents: Option<SaturationExponents>,
    /// Leave out the check against the map (`flux_map_check`: the held-out choice of the
    /// model, the no-load flux and the inductances against the map's own values), for
    /// Monte Carlo studies of the coefficients alone. Default false.
    pub skip_check: bool,
}

/// How many exponent candidates (best by the linear start) get the flux fit.
pub const FLUX_MAP_REFINED: usize = 4;

/// One exponent candidate: its exponents and the rms residuals of its linear start
/// (current, \[A\]) and, when refined, of its flux fit \[V s\].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExponentCandidate {
    /// `(S, T, U, V)`.
    pub exponents: SaturationExponents,
    /// The linear start's rms current residual \[A\].
    pub rms_current: f64,
    /// The flux fit's rms residual \[V s\] (`None`: not refined).
    pub rms_flux: Option<f64>,
}

/// A fitted flux map: the chosen exponents, the fit (coefficients with standard errors
/// and 95 % intervals), the residual against the map's range, and the inductances at a
/// few operating points.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FluxMapFit {
    /// The map's name.
    pub map: String,
    /// Operating points in the map.
    pub points: usize,
    /// The chosen exponents.
    pub exponents: SaturationExponents,
    /// The prediction-error fit in the flux (coefficients in [`SATURATION_PARAMETERS`](crate::pmsm::SATURATION_PARAMETERS) order).
    pub fit: FitResult,
    /// The fitted model.
    pub model: Saturation,
    /// The rms flux residual over both axes \[V s\].
    pub rms_residual: f64,
    /// The rms flux residual of `ψ_d` and of `ψ_q` \[V s\].
    #[serde(default)]
    pub rms_residual_dq: [f64; 2],
    /// The largest flux residual \[V s\] and the current `[i_d, i_q]` \[A\] where it is.
    pub max_residual: (f64, [f64; 2]),
    /// The map's flux range: the largest of `max ψ_d − min ψ_d` and `max ψ_q − min ψ_q` \[V s\].
    pub range: f64,
    /// The candidates tried, best linear start first.
    pub candidates: Vec<ExponentCandidate>,
    /// Apparent and incremental inductances of the saturation model at zero current, at the
    /// map's largest `|i_q|` (half and full, `i_d = 0`) and at its most negative `i_d` with
    /// the largest `i_q` (on the map's grid, where it has one).
    pub operating_points: Vec<Inductances>,
    /// The figures a user reads off the map (no-load flux, incremental inductances with
    /// intervals) from the model with the least held-out error, checked against the map
    /// (`None` with [`FluxMapOptions::skip_check`]).
    pub check: Option<MapCheck>,
    /// The saturation model refitted on regions of the map, and its coefficients' intervals
    /// widened where they disagree (`None` with [`FluxMapOptions::skip_check`] or a map too
    /// small to split).
    #[serde(default)]
    pub regions: Option<RegionCheck>,
    /// What a reader should know about the fit: an exponent chosen at the edge of the
    /// searched range, a printed operating point outside the map's currents.
    #[serde(default)]
    pub notes: Vec<String>,
}

/// Fits the saturation model ([`Saturation`]) to a flux map read by
/// [`read_flux_map`](crate::pmsm::read_flux_map) (channels `i_d`, `i_q`, `psi_d`, `psi_q`).
///
/// # Errors
/// [`Error::MissingChannel`] for a map without those channels; [`Error::Numerical`] when no
/// exponent candidate gives a usable linear start (a map without saturation-free points
/// or with one axis constant); those of [`fit`].
pub fn fit_flux_map(map: &Experiment, options: &FluxMapOptions) -> Result<FluxMapFit> {
    let [i_d, i_q, psi_d, psi_q] = ["i_d", "i_q", "psi_d", "psi_q"].map(|c| map.channel(c));
    let (i_d, i_q, psi_d, psi_q) = (i_d?, i_q?, psi_d?, psi_q?);
    let grid: Vec<SaturationExponents> = match options.exponents {
        Some(e) => vec![e],
        None => (1..=9)
            .flat_map(|s| {
                (1..=9).flat_map(move |t| (0..=2).flat_map(move |u| (0..=2).map(move |v| (s, t, u, v))))
            })
            .map(|(s, t, u, v)| SaturationExponents { s, t, u, v })
            .collect(),
    };
    let mut starts: Vec<(SaturationExponents, Saturation, f64)> = grid
        .into_iter()
        .filter_map(|e| linear_start(e, i_d, i_q, psi_d, psi_q).map(|(m, rms)| (e, m, rms)))
        .collect();
    starts.sort_by(|a, b| a.2.total_cmp(&b.2));
    if starts.is_empty() {
        return Err(Error::Numerical {
            context: format!("flux map `{}`", map.name()),
            reason: "no linear start: the map needs currents and fluxes that vary on both axes".into(),
        });
    }
    let mut best: Option<(usize, FitResult, f64)> = None;
    let mut rms_flux = vec![None; starts.len()];
    for (j, (e, start, _)) in starts.iter().enumerate().take(FLUX_MAP_REFINED) {
        let theta = start.theta();
        let model = FluxMapModel::new(*e, &theta);
        let Ok(result) = fit(&model, std::slice::from_ref(map), &theta, &PemOptions::default()) else {
            continue;
        };
        let rms = rms_of(&result);
        rms_flux[j] = Some(rms);
        if best.as_ref().is_none_or(|b| rms < b.2) {
            best = Some((j, result, rms));
        }
    }
    let Some((j, result, rms_residual)) = best else {
        return Err(Error::Numerical {
            context: format!("flux map `{}`", map.name()),
            reason: "the flux fit failed from every candidate start".into(),
        });
    };
    let exponents = starts[j].0;
    let values: Vec<f64> = result.parameters.iter().map(|p| p.value).collect();
    let model = Saturation::from_theta(&values, exponents);
    let mut max_residual = (0.0, [0.0; 2]);
    for k in 0..map.len() {
        let psi = model.flux([i_d[k], i_q[k]])?;
        let r = (psi[0] - psi_d[k]).hypot(psi[1] - psi_q[k]);
        if r > max_residual.0 {
            max_residual = (r, [i_d[k], i_q[k]]);
        }
    }
    let span = |v: &[f64]| {
        v.iter().copied().fold(f64::NEG_INFINITY, f64::max) - v.iter().copied().fold(f64::INFINITY, f64::min)
    };
    let q_max = i_q.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let d_min = i_d.iter().copied().fold(0.0_f64, f64::min);
    let at = [[0.0, 0.0], [0.0, 0.5 * q_max], [0.0, q_max], [d_min, q_max]];
    let check = (!options.skip_check).then(|| check(map, exponents, &result, &at)).transpose()?;
    let (regions, region_note) =
        if options.skip_check { (None, None) } else { regions(map, exponents, &result) };
    // The points whose figures the report prints: the no-load flux's zero current and the
    // inductances' operating points.
    let printed: Vec<[f64; 2]> = match &check {
        Some(c) => std::iter::once([0.0, 0.0]).chain(c.points.iter().map(|p| p.i)).collect(),
        None => at.to_vec(),
    };
    let operating_points = match &check {
        Some(c) => c.points.iter().map(|p| model.inductances(p.i)).collect::<Result<Vec<_>>>()?,
        None => at.into_iter().map(|i| model.inductances(i)).collect::<Result<Vec<_>>>()?,
    };
    let candidates = starts
        .iter()
        .zip(rms_flux)
        .map(|((e, _, rms_current), rms_flux)| ExponentCandidate {
            exponents: *e,
            rms_current: *rms_current,
            rms_flux,
        })
        .collect();
    Ok(FluxMapFit {
        map: map.name().into(),
        points: map.len(),
        exponents,
        model,
        rms_residual,
        max_residual,
        range: span(psi_d).max(span(psi_q)),
        candidates,
        operating_points,
        check,
        regions,
        notes: notes(options.exponents.is_none(), exponents, &printed, i_d, i_q)
            .into_iter()
            .chain(region_note)
            .collect(),
        rms_residual_dq: [0, 1].map(|k| result.fit.rms_residual.get(k).copied().unwrap_or(f64::NAN)),
        fit: result,
    })
}

/// The notes of a fit ([`FluxMapFit::notes`]): with the exponents `searched`, any of
/// `e` at the edge of the search's range (`S` or `T` 9, `U` or `V` 2: a wider range might
/// fit better); any `printed` point outside the map's range of `i_d` or `i_q`.
fn notes(
    searched: bool,
    e: SaturationExponents,
    printed: &[[f64; 2]],
    i_d: &[f64],
    i_q: &[f64],
) -> Vec<String> {
    let mut notes = Vec::new();
    let edge: Vec<String> = [("S", e.s, 9), ("T", e.t, 9), ("U", e.u, 2), ("V", e.v, 2)]
        .iter()
        .filter(|(_, x, top)| searched && x == top)
        .map(|(n, x, _)| format!("{n} = {x}"))
        .collect();
    if !edge.is_empty() {
        notes.push(format!(
            "exponent {} at the edge of the searched range (S, T 1..9; U, V 0..2): a larger one may fit better; \
             try it with --exponents",
            edge.join(", ")
        ));
    }
    let range =
        |v: &[f64]| v.iter().fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], x| [lo.min(*x), hi.max(*x)]);
    let (d, q) = (range(i_d), range(i_q));
    for (j, p) in printed.iter().enumerate() {
        if printed[..j].contains(p) {
            continue;
        }
        let inside = |x: f64, [lo, hi]: [f64; 2]| x >= lo - 1e-9 * (hi - lo) && x <= hi + 1e-9 * (hi - lo);
        if !(inside(p[0], d) && inside(p[1], q)) {
            notes.push(format!(
                "the point i = ({:.2}, {:.2}) A, whose figures the report prints, lies outside the map (i_d {:.2} … {:.2} A, i_q {:.2} … {:.2} A): \
                 its figures are the model's extrapolation",
                p[0], p[1], d[0], d[1], q[0], q[1]
            ));
        }
    }
    notes
}

/// The rms residual over both outputs of a fit \[their unit\].
fn rms_of(result: &FitResult) -> f64 {
    let r = &result.fit.rms_residual;
    (r.iter().map(|x| x * x).sum::<f64>() / r.len().max(1) as f64).sqrt()
}

/// The least-squares coefficients of `i(ψ)` (linear in them given the measured flux) with
/// the magnets' MMF `i_f`, turned into a valid model (saturation terms clipped at zero,
/// `ψ_f` from `i_f`), and the rms current residual \[A\]; `None` if the system is singular
/// or the unsaturated coefficients come out non-positive.
fn linear_start(
    e: SaturationExponents,
    i_d: &[f64],
    i_q: &[f64],
    psi_d: &[f64],
    psi_q: &[f64],
) -> Option<(Saturation, f64)> {
    let n = i_d.len();
    let p = |x: f64, k: u32| x.abs().powi(k as i32);
    let mut a = DMatrix::<f64>::zeros(2 * n, 6);
    let mut b = DVector::<f64>::zeros(2 * n);
    for k in 0..n {
        let (d, q) = (psi_d[k], psi_q[k]);
        // Unknowns: a_d0, a_dd, a_q0, a_qq, a_dq, i_f.
        let row_d = [d, p(d, e.s) * d, 0.0, 0.0, p(d, e.u) * p(q, e.v + 2) / f64::from(e.v + 2) * d, -1.0];
        let row_q = [0.0, 0.0, q, p(q, e.t) * q, p(d, e.u + 2) * p(q, e.v) / f64::from(e.u + 2) * q, 0.0];
        for j in 0..6 {
            a[(2 * k, j)] = row_d[j];
            a[(2 * k + 1, j)] = row_q[j];
        }
        b[2 * k] = i_d[k];
        b[2 * k + 1] = i_q[k];
    }
    // Column scaling, then an SVD solve (the columns differ by orders of magnitude).
    let norms: Vec<f64> = (0..6).map(|j| a.column(j).norm()).collect();
    if norms.iter().any(|&c| !(c > 0.0 && c.is_finite())) {
        return None;
    }
    for (j, c) in norms.iter().enumerate() {
        a.column_mut(j).scale_mut(1.0 / c);
    }
    let x = a.clone().svd(true, true).solve(&b, 1e-12).ok()?;
    let rms = ((&a * &x - &b).norm_squared() / (2 * n) as f64).sqrt();
    let x: Vec<f64> = x.iter().zip(&norms).map(|(v, c)| v / c).collect();
    if !(x[0] > 0.0 && x[2] > 0.0 && rms.is_finite()) {
        return None;
    }
    let mut m = Saturation {
        a_d0: x[0],
        a_dd: x[1].max(0.0),
        a_q0: x[2],
        a_qq: x[3].max(0.0),
        a_dq: x[4].max(0.0),
        psi_f: 0.0,
        exponents: e,
    };
    // ψ_f from i_f: (a_d0 + a_dd |ψ|^S) ψ = i_f, monotone in ψ.
    let mut psi = x[5] / m.a_d0;
    for _ in 0..100 {
        let f = (m.a_d0 + m.a_dd * p(psi, e.s)) * psi - x[5];
        let df = m.a_d0 + f64::from(e.s + 1) * m.a_dd * p(psi, e.s);
        let step = f / df;
        psi -= step;
        if step.abs() <= 1e-15 * (1.0 + psi.abs()) {
            break;
        }
    }
    m.psi_f = psi;
    (m.check().is_ok() && m.flux([0.0, 0.0]).is_ok()).then_some((m, rms))
}

impl std::fmt::Display for FluxMapFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let e = self.exponents;
        writeln!(f, "Flux map `{}`: {} operating points", self.map, self.points)?;
        writeln!(
            f,
            "Saturation model (Hinkkanen et al. 2017, PM as a d-axis MMF), exponents S = {}, T = {}, U = {}, V = {}",
            e.s, e.t, e.u, e.v
        )?;
        write!(f, "\n{}", estimate_table(&self.fit))?;
        writeln!(
            f,
            "\nrms flux residual ψ_d {:.3e} V s, ψ_q {:.3e} V s (together {:.3e} V s = {:.3} % of the map's range {:.4} \
             V s); largest |ψ − ψ_map| {:.3e} V s at i = ({:.1}, {:.1}) A",
            self.rms_residual_dq[0],
            self.rms_residual_dq[1],
            self.rms_residual,
            100.0 * self.rms_residual / self.range,
            self.range,
            self.max_residual.0,
            self.max_residual.1[0],
            self.max_residual.1[1]
        )?;
        let u = &self.fit.uncertainty;
        let worst = u.ljung_box.iter().copied().fold(0.0, f64::max);
        match u.method {
            crate::estimate::CovarianceMethod::BatchMeans => {
                writeln!(f, "standard errors: batch means over {} batches (residuals not white)", u.batches)?
            }
            _ if worst > u.ljung_box_critical => writeln!(
                f,
                "standard errors: white residuals assumed, but the residuals are not white (Ljung–Box {worst:.0} > \
                 {:.0}): model error dominates them, so the standard errors understate the coefficients' \
                 uncertainty (the map is too small for batch means)",
                u.ljung_box_critical
            )?,
            _ => writeln!(
                f,
                "standard errors: white residuals (Ljung–Box {worst:.1} ≤ {:.1})",
                u.ljung_box_critical
            )?,
        }
        if let Some(r) = &self.regions {
            write!(f, "{r}")?;
        }
        f.write_str(&inductance_table(&self.operating_points))?;
        let refined: Vec<String> = self
            .candidates
            .iter()
            .filter_map(|c| {
                c.rms_flux.map(|r| {
                    let e = c.exponents;
                    format!("({},{},{},{}) {:.3e} V s", e.s, e.t, e.u, e.v, r)
                })
            })
            .collect();
        if self.candidates.len() > 1 {
            writeln!(f, "\nexponents (S,T,U,V) refined, rms flux residual: {}", refined.join("; "))?;
        }
        if let Some(c) = &self.check {
            write!(f, "{c}")?;
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        Ok(())
    }
}

/// The operating points' apparent and incremental inductances as a text table \[mH\].
pub(super) fn inductance_table(points: &[Inductances]) -> String {
    let mut t = String::from(
        "\nInductances [mH] (apparent L_d = (ψ_d − ψ_f)/i_d, L_q = ψ_q/i_q; incremental ∂ψ/∂i):\n",
    );
    t += &format!(
        "{:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>9}\n",
        "i_d [A]", "i_q [A]", "L_d app", "L_q app", "L_dd", "L_qq", "L_dq"
    );
    let mh = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{:.3}", 1e3 * v));
    for p in points {
        t += &format!(
            "{:>8.2} {:>8.2} {:>9} {:>9} {:>9.3} {:>9.3} {:>9.4}\n",
            p.i[0],
            p.i[1],
            mh(p.l_d_apparent),
            mh(p.l_q_apparent),
            1e3 * p.l_dd,
            1e3 * p.l_qq,
            1e3 * p.l_dq
        );
    }
    t
}
