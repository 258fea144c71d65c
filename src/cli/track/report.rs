//! The summary line and the JSON of `greybox track` (shape in [`super::TrackArgs`]): the
//! final estimates, with their standard errors and 95 % intervals where the estimator gives
//! them, and the temperatures where a reference is given.

use crate::online::{TemperatureTrajectory, Trajectory};
use crate::pmsm::ThermalReference;
use serde_json::{Value, json};

/// `K_t = √(3/2) K_e`.
fn k_t_of(k_e: f64) -> f64 {
    1.5f64.sqrt() * k_e
}

/// The summary line of a run named `name` (`n_p` pole pairs; `thermal`: the temperatures'
/// reference).
pub(super) fn summary_line(
    name: &str,
    tr: &Trajectory,
    n_p: u32,
    thermal: Option<&ThermalReference>,
) -> String {
    let f = &tr.final_estimate;
    let mut line = match tr.final_se() {
        None => format!(
            "{name}: K_e = {:.6} V s/rad, K_t = {:.6} N m/A, R_s = {:.6} ohm ({} observer steps, to t = {:.4} s)",
            f.k_e,
            f.k_t,
            f.r_s,
            tr.t.len(),
            tr.t.last().copied().unwrap_or(0.0)
        ),
        Some((k_se, r_se)) => format!(
            "{name}: K_e = {:.6} ± {:.2e} V s/rad, K_t = {:.6} ± {:.2e} N m/A, R_s = {:.6} ± {:.2e} ohm (95 %; \
             {} filter steps, to t = {:.4} s)",
            f.k_e,
            1.96 * k_se,
            f.k_t,
            1.96 * k_t_of(k_se),
            f.r_s,
            1.96 * r_se,
            tr.t.len(),
            tr.t.last().copied().unwrap_or(0.0)
        ),
    };
    if let Some(reference) = thermal {
        let last = last_point(tr).temperatures(n_p, reference);
        for (label, v, se) in [
            ("T_winding", &last.t_winding, &last.t_winding_se),
            ("T_magnet", &last.t_magnet, &last.t_magnet_se),
        ] {
            if let (Some(v), Some(se)) = (v.first(), se.first()) {
                line += &if se.is_finite() {
                    format!("; {label} = {v:.1} ± {:.1} °C", 1.96 * se)
                } else {
                    format!("; {label} = {v:.1} °C")
                };
            }
        }
    }
    line
}

/// The trajectory's last point alone.
fn last_point(tr: &Trajectory) -> Trajectory {
    tr.decimate(1)
}

/// The temperatures' JSON fields of `temps`, each with its standard error where finite
/// (`json!` writes a non-finite number as null).
fn temperature_fields(temps: &TemperatureTrajectory, at: Option<usize>) -> serde_json::Map<String, Value> {
    let mut out = serde_json::Map::new();
    for (name, v) in [
        ("t_winding", &temps.t_winding),
        ("t_winding_se", &temps.t_winding_se),
        ("t_magnet", &temps.t_magnet),
        ("t_magnet_se", &temps.t_magnet_se),
    ] {
        if v.is_empty() {
            continue;
        }
        out.insert(
            name.into(),
            match at {
                Some(k) => json!(v[k]),
                None => json!(v),
            },
        );
    }
    out
}

/// The JSON of the runs, trajectories decimated to `max_points`.
pub(super) fn to_json(
    runs: &[(String, Trajectory)],
    max_points: usize,
    n_p: u32,
    thermal: Option<&ThermalReference>,
) -> String {
    let one = |tr: &Trajectory| {
        let d = tr.decimate(max_points);
        let f = &tr.final_estimate;
        // `json!` writes a non-finite f64 as null.
        let mut v = match tr.final_se() {
            None => json!({
                "final": {
                    "k_e": f.k_e, "k_t": f.k_t, "r_s": f.r_s,
                    "innovation_ratio": tr.innovation_ratio, "trusted": tr.consistent(),
                },
                "trajectory": { "t": d.t, "k_e": d.k_e, "r_s": d.r_s },
            }),
            Some((k_se, r_se)) => json!({
                "final": {
                    "k_e": f.k_e, "k_t": f.k_t, "r_s": f.r_s,
                    "k_e_se": k_se, "k_t_se": k_t_of(k_se), "r_s_se": r_se,
                    "innovation_ratio": tr.innovation_ratio, "trusted": tr.consistent(),
                },
                "trajectory": { "t": d.t, "k_e": d.k_e, "r_s": d.r_s, "k_e_se": d.k_e_se, "r_s_se": d.r_s_se },
            }),
        };
        if let Some(reference) = thermal {
            let last = last_point(tr).temperatures(n_p, reference);
            let along = d.temperatures(n_p, reference);
            for (key, fields) in [
                ("final", temperature_fields(&last, Some(0))),
                ("trajectory", temperature_fields(&along, None)),
            ] {
                if let Some(o) = v[key].as_object_mut() {
                    o.extend(fields);
                }
            }
        }
        v
    };
    let v = match runs {
        [(_, tr)] => one(tr),
        _ => {
            let logs: Vec<Value> = runs
                .iter()
                .map(|(name, tr)| {
                    let mut o = one(tr);
                    o["log"] = json!(name);
                    o
                })
                .collect();
            json!({ "logs": logs })
        }
    };
    serde_json::to_string_pretty(&v).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
}
