//! `greybox design`: the predicted standard errors, 95 % intervals, error indices and
//! optimality criteria of planned experiments (scenarios or scenario files) side by side,
//! ranked by D-, A- or E-optimality, and optionally the shortest plan of a knob search that
//! reaches target intervals (issue 32). One noise-free simulation and one normal-equation
//! pass per plan ([`crate::drive::predict_plan`]): the Cramér–Rao bound (Ljung,
//! *System Identification*, 2nd ed., 9.3 and 13; Wang & Dowling, AIChE J. 68 (2022) e17813).

use super::output;
use super::simulate::MotorArg;
use crate::Error;
use crate::app::set_field;
use crate::data::Staged;
use crate::drive::{DQ_PER_PHASE_VARIANCE, PlanPrediction, predict_plan};
use crate::drive::{DriveConfig, IPM_MOTOR, SCENARIOS, SPM_MOTOR};
use crate::drive::{Grid, Knobs, PLANS, planned_drive};
use crate::estimate::design::{Criterion, SearchOutcome, Target, search_shortest};
use crate::pmsm::{MotorKind, SavedModel};
use crate::report::plot::write_svg;
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};

mod report;
pub use report::{DesignReport, SearchReport, SearchedCandidate};
use report::{plot, text};

/// Arguments of `greybox design`.
#[derive(Args, Debug)]
#[command(after_help = "Plans: the thesis scenarios exp1-exp6 and the planned injections exp3_id_const \
(constant i_d = -0.5 i_max) and exp3_id_pulses (-0.7 i_max pulses of 0.2 s every 0.4 s), or scenario files \
(greybox simulate --print-config). The prediction is for `greybox fit` with its defaults on the terminal voltage; \
voltage and speed noise are errors in variables and not in it. See docs/design.md.")]
pub struct DesignArgs {
    /// A planned experiment by name (repeatable): exp1 … exp6, exp3_id_const, exp3_id_pulses.
    #[arg(long)]
    pub scenario: Vec<String>,
    /// A planned experiment as a scenario file (repeatable; JSON, as `greybox simulate
    /// --print-config` writes it).
    #[arg(long)]
    pub config: Vec<PathBuf>,
    /// The motor of the named plans.
    #[arg(long, value_enum, default_value_t = MotorArg::Spm)]
    pub motor: MotorArg,
    /// Record length of every plan [s].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Set a field of every plan by its path in the scenario file, e.g. `motor.r_s=1.1`,
    /// `control.i_max=8` (repeatable; after --params).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// Nominal parameters (and, without --current-noise, the noise) from a fit report
    /// (`greybox fit --json`).
    #[arg(long, value_name = "REPORT.json")]
    pub params: Option<PathBuf>,
    /// Phase-current noise σ [A] (white, or AR(1) with --current-noise-pole).
    #[arg(long, value_name = "A")]
    pub current_noise: Option<f64>,
    /// AR(1) pole of the current noise, in [0, 1).
    #[arg(long, value_name = "a")]
    pub current_noise_pole: Option<f64>,
    /// The criterion the plans are ranked by.
    #[arg(long, value_enum, default_value_t = CriterionArg::D)]
    pub criterion: CriterionArg,
    /// Search the design knobs around each plan for the shortest run reaching the targets.
    #[arg(long, requires = "target")]
    pub search: bool,
    /// Target relative 95 % half-width of a parameter, e.g. `r_s=0.5%` (repeatable).
    #[arg(long, value_name = "NAME=HALF_WIDTH")]
    pub target: Vec<String>,
    /// Search: d-current injection amplitudes [fraction of i_max] (comma-separated).
    #[arg(long, value_delimiter = ',', default_values_t = Grid::default().amplitudes)]
    pub amplitudes: Vec<f64>,
    /// Search: injection pulse lengths [s] (0: a constant injection).
    #[arg(long, value_delimiter = ',', default_values_t = Grid::default().pulses)]
    pub pulses: Vec<f64>,
    /// Search: time between injection pulse starts [s].
    #[arg(long, default_value_t = Grid::default().period)]
    pub pulse_period: f64,
    /// Search: factors on the speed (or position) reference.
    #[arg(long, value_delimiter = ',', default_values_t = Grid::default().speed_scales)]
    pub speed_scales: Vec<f64>,
    /// Search: record lengths [s].
    #[arg(long, value_delimiter = ',', default_values_t = Grid::default().durations)]
    pub durations: Vec<f64>,
    /// Write the report (every plan's prediction, the ranking, the search) as JSON ("-": stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Plot the predicted 95 % intervals [% of nominal] per parameter and plan (SVG).
    #[arg(long, value_name = "PATH.svg")]
    pub plot: Option<PathBuf>,
    /// Write the search's shortest plan as a scenario file (for `greybox simulate --config`).
    #[arg(long, value_name = "PATH.json", requires = "search")]
    pub best_config: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// The ranking criterion (`--criterion`): `d`, `a` or `e` (see [`Criterion`]).
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum CriterionArg {
    D,
    A,
    E,
}

/// Runs `greybox design`.
///
/// # Errors
/// An unknown plan or field, an unreadable scenario file or report, no or zero noise, a bad
/// target, a failing simulation, an output that cannot be written (nothing is written then).
pub fn run_design(a: &DesignArgs) -> crate::Result<()> {
    let inputs: Vec<PathBuf> = a.config.iter().chain(&a.params).cloned().collect();
    output::check_all(
        &[
            ("--json", a.json.as_deref()),
            ("--plot", a.plot.as_deref()),
            ("--best-config", a.best_config.as_deref()),
        ],
        &inputs,
    )?;
    let (plans, noise_source) = plans(a)?;
    let criterion = match a.criterion {
        CriterionArg::D => Criterion::D,
        CriterionArg::A => Criterion::A,
        CriterionArg::E => Criterion::E,
    };
    let predictions = plans.iter().map(predict_plan).collect::<crate::Result<Vec<_>>>()?;
    let scores: Vec<_> = predictions.iter().map(|p| p.prediction.clone()).collect();
    let ranking = criterion.rank(&scores).into_iter().map(|i| predictions[i].plan.clone()).collect();
    let (search, best_config) =
        if a.search { search(a, &plans).map(|(r, c)| (Some(r), c))? } else { (None, None) };
    let report = DesignReport { criterion, noise_source, plans: predictions, ranking, search };
    if !(a.quiet || a.json.as_ref().is_some_and(|p| p.as_os_str() == "-")) {
        output::stdout(&text(&report, &plans))?;
    }
    let mut staged = Staged::new();
    if let Some(path) = &a.json {
        output::write(&mut staged, path, &serde_json::to_string_pretty(&report).unwrap_or_default())?;
    }
    if let Some(path) = &a.plot {
        let svg = plot(&report)?;
        staged.produce(path, |tmp| write_svg(tmp, &svg))?;
    }
    if let (Some(path), Some(cfg)) = (&a.best_config, &best_config) {
        output::write(&mut staged, path, &serde_json::to_string_pretty(cfg).unwrap_or_default())?;
    }
    staged.commit()
}

/// The plans of the flags, with their nominal parameters and noise, and where the noise
/// came from.
///
/// # Errors
/// An unknown plan or field, an unreadable file, no plan, no or zero noise.
pub fn plans(a: &DesignArgs) -> crate::Result<(Vec<DriveConfig>, String)> {
    let motor = match a.motor {
        MotorArg::Spm => SPM_MOTOR,
        MotorArg::Ipm => IPM_MOTOR,
        MotorArg::IpmSat => {
            return Err(Error::InvalidOption {
                option: "--motor".into(),
                reason:
                    "ipm-sat: the design predicts the linear fits of `greybox fit`; plan with --motor ipm"
                        .into(),
            });
        }
    };
    if a.scenario.is_empty() && a.config.is_empty() {
        return Err(Error::InvalidOption {
            option: "scenario".into(),
            reason: format!(
                "give at least one plan: --scenario ({}, {}) or --config FILE",
                SCENARIOS.join(", "),
                PLANS.join(", ")
            ),
        });
    }
    let mut plans = a.scenario.iter().map(|n| planned_drive(n, motor)).collect::<crate::Result<Vec<_>>>()?;
    for path in &a.config {
        let text =
            std::fs::read_to_string(path).map_err(|source| Error::Io { path: path.clone(), source })?;
        let mut cfg: DriveConfig = serde_json::from_str(&text).map_err(|e| Error::InvalidOption {
            option: "config".into(),
            reason: format!("{}: {e}", path.display()),
        })?;
        cfg.name = path.file_stem().map_or(cfg.name, |s| s.to_string_lossy().into_owned());
        plans.push(cfg);
    }
    let report = a.params.as_deref().map(|p| read_report(p, motor.n_p)).transpose()?;
    let noise_flag = a.current_noise.map(|s| (s, a.current_noise_pole.unwrap_or(0.0)));
    let mut source = "plans".to_string();
    for cfg in &mut plans {
        if let Some(d) = a.duration {
            cfg.duration = d;
        }
        if let Some((saved, _)) = &report {
            cfg.motor = nominal(saved);
        }
        for s in &a.set {
            *cfg = set_field(cfg, s)?;
        }
        if let Some((sd, pole)) = noise_flag {
            (cfg.sensors.current_noise, cfg.sensors.current_noise_pole) = (sd, pole);
            source = "flags".into();
        } else if let Some((_, Some((sd, pole)))) = &report {
            (cfg.sensors.current_noise, cfg.sensors.current_noise_pole) =
                (*sd, a.current_noise_pole.unwrap_or(*pole));
            source = "params (residuals of the fit report)".into();
        } else if let Some(pole) = a.current_noise_pole {
            cfg.sensors.current_noise_pole = pole;
        }
        let s = &cfg.sensors;
        if !(s.current_noise.is_finite() && s.current_noise > 0.0) {
            return Err(Error::InvalidOption {
                option: "current-noise".into(),
                reason: format!(
                    "plan `{}`: the phase-current noise σ is {} A; give a positive --current-noise A (or \
                     --params REPORT.json to take it from a fit's residuals)",
                    cfg.name, s.current_noise
                ),
            });
        }
        if !(0.0..1.0).contains(&s.current_noise_pole) {
            return Err(Error::InvalidOption {
                option: "current-noise-pole".into(),
                reason: format!("{} is outside [0, 1)", s.current_noise_pole),
            });
        }
        cfg.validate()?;
    }
    Ok((plans, source))
}

/// A fit report: its model and the phase-current noise σ \[A\] and AR(1) pole its residuals
/// imply (`None` without residual statistics: a least-squares report). The dq residual
/// variance is `4/3` of the phase variance ([`DQ_PER_PHASE_VARIANCE`]); the pole is the
/// residuals' lag-1 autocorrelation (mean over the outputs, clamped to \[0, 0.99\]).
fn read_report(path: &Path, n_p: u32) -> crate::Result<(SavedModel, Option<(f64, f64)>)> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io { path: path.into(), source })?;
    let saved = SavedModel::from_json(&text, None, None)
        .or_else(|_| SavedModel::from_json(&text, Some(n_p), None))?;
    let value: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
    let fit = &value["fit"];
    let rms: Vec<f64> =
        fit["rms_residual"].as_array().into_iter().flatten().filter_map(|v| v.as_f64()).collect();
    let lag1: Vec<f64> = fit["whiteness"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|w| w["autocorrelation"].get(0).and_then(|v| v.as_f64()))
        .collect();
    let noise = (!rms.is_empty() && rms.iter().all(|r| r.is_finite() && *r > 0.0)).then(|| {
        let dq_var = rms.iter().map(|r| r * r).sum::<f64>() / rms.len() as f64;
        let pole = if lag1.is_empty() { 0.0 } else { lag1.iter().sum::<f64>() / lag1.len() as f64 };
        ((dq_var / DQ_PER_PHASE_VARIANCE).sqrt(), pole.clamp(0.0, 0.99))
    });
    Ok((saved, noise))
}

/// The motor of a saved fit: `R_s`, `L_d`, `L_q` (`L_s` for both), `ψ_f = √(2/3) K_e / n_p`
/// (MODEL.md §2), its pole pairs.
fn nominal(saved: &SavedModel) -> crate::pmsm::MotorParameters {
    let t = &saved.theta;
    let (l_d, l_q, k_e) = match saved.kind {
        MotorKind::Spm => (t[1], t[1], t[2]),
        MotorKind::Ipm => (t[1], t[2], t[3]),
    };
    let n_p = saved.pole_pairs;
    crate::pmsm::MotorParameters {
        r_s: t[0],
        l_d,
        l_q,
        psi_f: (2.0f64 / 3.0).sqrt() * k_e / f64::from(n_p),
        n_p,
    }
}

/// The knob search around every plan: the report and the winner's scenario.
fn search(a: &DesignArgs, plans: &[DriveConfig]) -> crate::Result<(SearchReport, Option<DriveConfig>)> {
    let targets = a.target.iter().map(|t| t.parse::<Target>()).collect::<crate::Result<Vec<_>>>()?;
    let grid = Grid {
        amplitudes: a.amplitudes.clone(),
        pulses: a.pulses.clone(),
        period: a.pulse_period,
        speed_scales: a.speed_scales.clone(),
        durations: a.durations.clone(),
    };
    let knobs = grid.candidates()?;
    let configs: Vec<DriveConfig> = plans.iter().flat_map(|p| knobs.iter().map(|k| k.apply(p))).collect();
    let all_knobs: Vec<Knobs> = plans.iter().flat_map(|_| knobs.iter().copied()).collect();
    let lengths: Vec<f64> = configs.iter().map(|c| c.duration).collect();
    let mut predicted: Vec<Option<PlanPrediction>> = vec![None; configs.len()];
    let outcome: SearchOutcome = search_shortest(&lengths, &targets, |i| {
        Ok(match predict_plan(&configs[i]) {
            Err(e) => Err(format!("not predicted: {e}")),
            Ok(p) => match p.limits.reached() {
                Some(limit) => Err(limit),
                None => {
                    let prediction = p.prediction.clone();
                    predicted[i] = Some(p);
                    Ok(prediction)
                }
            },
        })
    })?;
    let candidates = outcome
        .evaluated
        .iter()
        .map(|c| SearchedCandidate {
            name: configs[c.index].name.clone(),
            knobs: all_knobs[c.index],
            achieved: c.achieved.clone(),
            rejected: c.rejected.clone(),
            reaches: c.reaches,
        })
        .collect();
    let best = outcome.best.and_then(|i| predicted[i].take());
    let config = outcome.best.map(|i| configs[i].clone());
    Ok((SearchReport { targets, candidates, best }, config))
}
