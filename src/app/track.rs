//! What a user asks of the online estimators, typed ([`TrackRequest`]): the options of
//! `greybox track` and of the Python `track`, without their spelling and without the
//! outputs each writes; [`track_logs`] runs the estimator asked for over each log.
//! Errors name the options as the command line's flags (`--gamma-ke`); Python rewrites
//! them as its keywords ([`super::words::keywords`]).

use super::request::LogReading;
use crate::error::{Error, Result};
use crate::online::{
    Adaptation, KalmanNoise, MrasConfig, Trajectory, current_noise, track, track_kalman_with,
};
use crate::pmsm::{CsvOptions, SavedModel, ThermalReference, VoltageHold, VoltageInput, applied_experiment};
use std::path::{Path, PathBuf};

/// The online estimator: the extended Kalman filter (the default) or the thesis' MRAS.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Estimator {
    /// The thesis' MRAS (thesis 5.1), the reference; no standard errors.
    Mras,
    /// The extended Kalman filter of `R_s` and `K_e` with standard errors (Simon 2006, §13.2).
    #[default]
    Ekf,
}

/// The MRAS's settings; `None`: [`MrasConfig::default`]'s. Refused with the Kalman filter.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MrasSettings {
    /// Adaptation gain γ_Ke of `K_e`, ≥ 0 (thesis 5.1.1).
    pub gamma_ke: Option<f64>,
    /// Adaptation gain γ_Rs of `R_s` \[Ω/(A s)\], ≤ 0 (thesis eq. 5.4).
    pub gamma_rs: Option<f64>,
    /// `R_s` adapts only while `|i_d|` exceeds this \[A\].
    pub i_d_threshold: Option<f64>,
    /// Observer feedback gain f \[1/s\], ≥ 0.
    pub observer_gain: Option<f64>,
    /// The adaptation law.
    pub adaptation: Option<Adaptation>,
    /// Time constant of the `K_e` estimate \[s\] (normalised adaptation).
    pub tau_ke: Option<f64>,
    /// Time constant of the `R_s` estimate \[s\] (normalised adaptation).
    pub tau_rs: Option<f64>,
}

/// The Kalman filter's noise model; `None`: its defaults ([`KalmanNoise::for_machine`] at
/// the log's current noise). Refused with the MRAS.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KalmanSettings {
    /// Standard deviation of the current noise \[A\] (each of `i_d`, `i_q`).
    pub current_noise: Option<f64>,
    /// `R_s`'s random walk after one second \[Ω/√s\].
    pub r_s_walk: Option<f64>,
    /// `K_e`'s random walk after one second \[V s/rad/√s\].
    pub k_e_walk: Option<f64>,
}

/// An online estimation as asked for: every option of `greybox track` that changes the
/// estimates (not its outputs), typed. Units SI.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackRequest {
    /// Pole pairs n_p.
    pub pole_pairs: u32,
    /// How the logs are read (segments with `split_gaps`, each tracked on its own).
    pub reading: LogReading,
    /// Stator inductance (with `l_q`: `L_d`) \[H\]; `None`: the report's (`params`).
    pub l_s: Option<f64>,
    /// q-axis inductance \[H\] of a salient machine; `None`: the report's, else none.
    pub l_q: Option<f64>,
    /// A fit's JSON report: inductances, initial estimates, hold and voltage input.
    pub params: Option<PathBuf>,
    /// Initial `K_e` \[V s/rad\]; `None`: the report's, else 0.
    pub k_e0: Option<f64>,
    /// Initial `R_s` \[Ω\]; `None`: the report's, else 0.
    pub r_s0: Option<f64>,
    /// The voltage hold of the log's source; `None`: the report's, else the stator hold.
    pub hold: Option<VoltageHold>,
    /// The estimator.
    pub estimator: Estimator,
    /// The MRAS's settings.
    pub mras: MrasSettings,
    /// The Kalman filter's settings.
    pub kalman: KalmanSettings,
    /// Reference temperature T_0 \[°C\] of `r_s_t0` and `psi_f_t0`.
    pub t0: Option<f64>,
    /// Winding resistance at T_0 \[Ω\].
    pub r_s_t0: Option<f64>,
    /// Magnet flux ψ_f at T_0 \[V s\].
    pub psi_f_t0: Option<f64>,
}

impl TrackRequest {
    /// The command line's defaults for a motor of `pole_pairs` pole pairs.
    pub fn new(pole_pairs: u32) -> Self {
        Self {
            pole_pairs,
            reading: LogReading::default(),
            l_s: None,
            l_q: None,
            params: None,
            k_e0: None,
            r_s0: None,
            hold: None,
            estimator: Estimator::default(),
            mras: MrasSettings::default(),
            kalman: KalmanSettings::default(),
            t0: None,
            r_s_t0: None,
            psi_f_t0: None,
        }
    }

    /// The temperatures' reference of `t0`, `r_s_t0`, `psi_f_t0` (MODEL.md §3), if given.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming `t0` for a reference value without it, and those of
    /// [`ThermalReference::try_new`].
    pub fn thermal(&self) -> Result<Option<ThermalReference>> {
        match (self.t0, self.r_s_t0, self.psi_f_t0) {
            (None, None, None) => Ok(None),
            (Some(t0), r, p) => ThermalReference::try_new(t0, r, p).map(Some).map_err(|e| match e {
                Error::InvalidOption { reason, .. } => Error::InvalidOption { option: "t0".into(), reason },
                e => e,
            }),
            (None, ..) => Err(Error::InvalidOption {
                option: "t0".into(),
                reason: "--r-s-t0 and --psi-f-t0 are values at a reference temperature: give it with --t0"
                    .into(),
            }),
        }
    }
}

/// One estimator run: the log's path, its segment (split at gaps, from 1) and the trajectory.
pub type TrackedLog = (PathBuf, Option<usize>, Trajectory);

/// Runs the estimator of `r` over every log of `logs` (each segment of a log split at its
/// gaps on its own), with the run names the command line prints (`LOG` or `LOG#k`), in the
/// order of the logs.
///
/// # Errors
/// An invalid setting (naming its flag), an unreadable `params` or log, an estimator that
/// fails on a log.
pub fn track_logs(logs: &[PathBuf], r: &TrackRequest) -> Result<(Vec<TrackedLog>, Vec<String>)> {
    let (config, input) = config(r)?;
    let csv = CsvOptions { pole_pairs: Some(r.pole_pairs), ..r.reading.csv.clone() };
    let groups = super::read_logs(logs, &csv, r.reading.split_gaps, false)?;
    let (mut runs, mut names) = (Vec::with_capacity(logs.len()), Vec::with_capacity(logs.len()));
    for (path, group) in logs.iter().zip(groups) {
        let one = group.len() == 1;
        for (k, log) in group.iter().enumerate() {
            // A fit from the reference voltage (`params`) drives the observer with the voltage
            // its delay and advance apply, as it drove the fit.
            let applied = match input {
                VoltageInput::Terminal => None,
                _ => Some(applied_experiment(log, r.pole_pairs, input).map_err(|e| flag_error(e, path))?),
            };
            let log = applied.as_ref().unwrap_or(log);
            let trajectory = match r.estimator {
                Estimator::Mras => track(log, &config),
                Estimator::Ekf => {
                    track_kalman_with(log, &config, |i_d, i_q| Ok(noise(&r.kalman, &config, i_d, i_q)))
                        .map_err(diverged)
                }
            }
            .map_err(|e| flag_error(e, path))?;
            let segment = (!one).then_some(k + 1);
            let name = path.display().to_string();
            names.push(segment.map_or_else(|| name.clone(), |k| format!("{name}#{k}")));
            runs.push((path.clone(), segment, trajectory));
        }
    }
    Ok((runs, names))
}

/// A numerical failure of the Kalman filter in the words of its likely cause: a filter
/// whose model does not fit the log diverges (its covariance stops being finite or
/// positive).
fn diverged(e: Error) -> Error {
    match e {
        Error::Numerical { context, reason } => Error::Numerical {
            context,
            reason: format!(
                "{reason}: the filter diverged, its model does not fit this log (check --l-s and --l-q or \
                 --params, --hold and the voltage the log gives)"
            ),
        },
        e => e,
    }
}

/// The Kalman filter's noise model of `k` for a log of the currents `i_d`, `i_q` \[A\]:
/// the current noise given or the log's own ([`current_noise`]), the walks given or their
/// defaults ([`KalmanNoise::for_machine`]).
fn noise(k: &KalmanSettings, config: &MrasConfig, i_d: &[f64], i_q: &[f64]) -> KalmanNoise {
    let sigma_i = k.current_noise.unwrap_or_else(|| current_noise(i_d, i_q));
    let d = KalmanNoise::for_machine(sigma_i, config.r_s0, config.k_e0);
    if k.r_s_walk.is_none() && k.k_e_walk.is_none() {
        return d;
    }
    // A walk given is absolute: the other one's default taken at the start.
    let (q_r, q_k) = d.walks_at(config.r_s0, config.k_e0);
    KalmanNoise { q_r_s: k.r_s_walk.unwrap_or(q_r), q_k_e: k.k_e_walk.unwrap_or(q_k), relative: false, ..d }
}

/// Refuses a setting of the estimator not chosen: the MRAS's with the Kalman filter (the
/// default), the filter's with the MRAS.
///
/// # Errors
/// [`Error::InvalidOption`] naming the first such flag.
fn other_estimators_settings(r: &TrackRequest) -> Result<()> {
    let m = &r.mras;
    let mras = [
        ("gamma-ke", m.gamma_ke.is_some()),
        ("gamma-rs", m.gamma_rs.is_some()),
        ("i-d-threshold", m.i_d_threshold.is_some()),
        ("observer-gain", m.observer_gain.is_some()),
        ("adaptation", m.adaptation.is_some()),
        ("tau-ke", m.tau_ke.is_some()),
        ("tau-rs", m.tau_rs.is_some()),
    ];
    let k = &r.kalman;
    let ekf = [
        ("current-noise", k.current_noise.is_some()),
        ("r-s-walk", k.r_s_walk.is_some()),
        ("k-e-walk", k.k_e_walk.is_some()),
    ];
    let (given, reason) = match r.estimator {
        Estimator::Ekf => (
            mras.iter().find(|f| f.1),
            "is a setting of the MRAS: add --estimator mras, or drop it for the Kalman filter (the default), \
             whose settings are --current-noise, --r-s-walk and --k-e-walk",
        ),
        Estimator::Mras => (
            ekf.iter().find(|f| f.1),
            "is a setting of the Kalman filter (--estimator ekf, the default): drop --estimator mras to use it",
        ),
    };
    match given {
        Some((flag, _)) => Err(Error::InvalidOption { option: (*flag).into(), reason: reason.into() }),
        None => Ok(()),
    }
}

/// The observer's settings of `r` (and `params`: its inductances, estimates, hold and
/// voltage input), validated before any log is read; errors name the flag.
fn config(r: &TrackRequest) -> Result<(MrasConfig, VoltageInput)> {
    other_estimators_settings(r)?;
    let d = MrasConfig::default();
    let saved = match &r.params {
        None => None,
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(|source| Error::Io { path: p.clone(), source })?;
            Some(SavedModel::from_json(&text, Some(r.pole_pairs), None)?)
        }
    };
    // The report's value of a parameter by name (SPM: r_s, l_s, k_e; IPM: r_s, l_d, l_q, k_e).
    let from_report = |name: &str| {
        let s = saved.as_ref()?;
        let i = s.kind.parameter_names().iter().position(|n| *n == name)?;
        s.theta.get(i).copied()
    };
    let l_s = r.l_s.or(from_report("l_s")).or(from_report("l_d")).ok_or_else(|| Error::InvalidOption {
        option: "l-s".into(),
        reason: "the observer needs the stator inductance: give --l-s H (with --l-q: L_d) or --params REPORT.json of a fit"
            .into(),
    })?;
    let m = &r.mras;
    let config = MrasConfig {
        n_p: r.pole_pairs,
        l_s,
        l_q: r.l_q.or(from_report("l_q")),
        h: 1.0, // replaced by each log's sample time in `track`
        f: m.observer_gain.unwrap_or(d.f),
        gamma_ke: m.gamma_ke.unwrap_or(d.gamma_ke),
        gamma_rs: m.gamma_rs.unwrap_or(d.gamma_rs),
        i_d_threshold: m.i_d_threshold.unwrap_or(d.i_d_threshold),
        adaptation: m.adaptation.unwrap_or(Adaptation::Normalised),
        tau_ke: m.tau_ke.unwrap_or(d.tau_ke),
        tau_rs: m.tau_rs.unwrap_or(d.tau_rs),
        k_e0: r.k_e0.or(from_report("k_e")).unwrap_or(0.0),
        r_s0: r.r_s0.or(from_report("r_s")).unwrap_or(0.0),
        hold: r.hold.unwrap_or_else(|| saved.as_ref().map_or(VoltageHold::Stator, |s| s.hold)),
    };
    config.validate().map_err(|e| flag_error(e, Path::new("")))?;
    if saved.as_ref().is_some_and(|s| s.inverter.is_some()) {
        return Err(Error::InvalidOption {
            option: "params".into(),
            reason: "the fit modelled the inverter's dead time, which the observer does not: give the report of a \
                     fit from the terminal voltage, or of one from the reference without --dead-time"
                .into(),
        });
    }
    Ok((config, saved.map_or(VoltageInput::Terminal, |s| s.input)))
}

/// Renames a [`MrasConfig`] field in an error to the flag that sets it; other errors name
/// the log (`log` empty: none).
fn flag_error(e: Error, log: &Path) -> Error {
    match e {
        Error::InvalidOption { option, reason } => {
            let flag = match option.as_str() {
                "n_p" => "pole-pairs",
                "l_s" => "l-s",
                "l_q" => "l-q",
                "f" => "observer-gain",
                "gamma_ke" => "gamma-ke",
                "gamma_rs" => "gamma-rs",
                "tau_ke" => "tau-ke",
                "tau_rs" => "tau-rs",
                "i_d_threshold" => "i-d-threshold",
                "k_e0" => "k-e0",
                "r_s0" => "r-s0",
                "sigma_i" => "current-noise",
                "q_r_s" => "r-s-walk",
                "q_k_e" => "k-e-walk",
                other => other,
            };
            Error::InvalidOption { option: flag.into(), reason }
        }
        // The observer's own failures name the sample, not the log.
        e @ (Error::NonFinite { .. } | Error::Numerical { .. }) if !log.as_os_str().is_empty() => {
            Error::Numerical {
                context: format!("the observer over {}", log.display()),
                reason: e.to_string(),
            }
        }
        e => e,
    }
}
