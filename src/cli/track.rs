//! `greybox track`: the MRAS observer (thesis 5.1) over each log, its final estimates and
//! their trajectory.

use super::args::ColumnArgs;
use super::output;
use crate::data::Staged;
use crate::online::{
    Adaptation, INNOVATION_RATIO_LIMIT, KalmanNoise, MrasConfig, Trajectory, current_noise, track,
    track_kalman,
};
use crate::pmsm::{CsvOptions, SavedModel, ThermalReference, VoltageHold, VoltageInput, applied_experiment};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

mod report;

/// Arguments of `greybox track`.
///
/// JSON shape (`--json`): one log gives
/// `{"final": {"k_e", "k_t", "r_s"}, "trajectory": {"t": [], "k_e": [], "r_s": []}}`
/// (with `--estimator ekf` also `k_e_se`, `k_t_se`, `r_s_se` in `final` and `k_e_se`,
/// `r_s_se` in `trajectory`: standard errors);
/// several logs give `{"logs": [{"log": PATH, "final": …, "trajectory": …}, …]}` in the
/// order given (PATH as given on the command line). Non-finite numbers are written as `null`.
#[derive(Args, Debug)]
#[command(
    after_help = "JSON (--json): one log gives {\"final\": {\"k_e\", \"k_t\", \"r_s\"}, \"trajectory\": \
{\"t\": [...], \"k_e\": [...], \"r_s\": [...]}}; several logs give {\"logs\": [{\"log\": PATH, \"final\": ..., \
\"trajectory\": ...}, ...]}, in the order given (PATH as given). With --estimator ekf, final and trajectory also \
carry the standard errors k_e_se, r_s_se (final: k_t_se). Units: k_e V s/rad, k_t N m/A, r_s ohm, t s. \
Non-finite numbers are null."
)]
pub struct TrackArgs {
    /// Drive logs (CSV, plain or gzip); the observer runs over each one separately.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Number of pole pairs n_p of the motor.
    #[arg(long, short = 'p')]
    pub pole_pairs: u32,
    /// Stator inductance L_s [H], known to the observer; with --l-q it is the d-axis
    /// inductance L_d (alias --l-d). Required unless --params gives it.
    #[arg(long, visible_alias = "l-d", allow_hyphen_values = true)]
    pub l_s: Option<f64>,
    /// q-axis inductance L_q [H] of a salient (interior-magnet) machine: the observer then
    /// steps the salient model with L_d = --l-s. Default: the report's l_q with an IPM
    /// --params, else none (surface magnets).
    #[arg(long, allow_hyphen_values = true)]
    pub l_q: Option<f64>,
    /// The JSON report of a fit (`greybox fit --json`): an SPM fit's l_s, or an IPM fit's
    /// (`--model ipm`) l_d and l_q, are the observer's inductances (unless --l-s, --l-q), its
    /// k_e and r_s the initial estimates (unless --k-e0, --r-s0), its hold the observer's
    /// (unless --hold); a fit from the reference voltage makes the observer read the log's
    /// ud_ref, uq_ref with that fit's delay and advance.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Initial estimate of K_e [V s/rad] (default: the report's with --params, else 0).
    #[arg(long, allow_hyphen_values = true)]
    pub k_e0: Option<f64>,
    /// Initial estimate of R_s [Ω] (default: the report's with --params, else 0).
    #[arg(long, allow_hyphen_values = true)]
    pub r_s0: Option<f64>,
    /// Adaptation gain γ_Ke of K_e, ≥ 0, for --adaptation lyapunov or relay (thesis 5.1.1;
    /// motor specific: a small L_s needs a much smaller one).
    /// MRAS only; default 0.001.
    #[arg(long, allow_hyphen_values = true)]
    pub gamma_ke: Option<f64>,
    /// Adaptation gain γ_Rs [Ω/(A s)] of R_s, ≤ 0, for --adaptation lyapunov or relay
    /// (thesis sign convention, eq. 5.4).
    /// MRAS only; default −10.
    #[arg(long, allow_hyphen_values = true)]
    pub gamma_rs: Option<f64>,
    /// R_s adapts only while |i_d| exceeds this [A], ≥ 0 (d-current injection; raise it
    /// above the current noise and the operating point's own i_d to adapt R_s on the
    /// injection only).
    /// MRAS only; default 0.5.
    #[arg(long, allow_hyphen_values = true)]
    pub i_d_threshold: Option<f64>,
    /// Observer feedback gain f [1/s], ≥ 0. MRAS only; default 100.
    #[arg(long, allow_hyphen_values = true)]
    pub observer_gain: Option<f64>,
    /// Adaptation law: normalised (gains set by the information each parameter receives,
    /// time constants --tau-ke and --tau-rs, no motor-specific gain), or the thesis' laws
    /// with --gamma-ke and --gamma-rs: lyapunov (K_e gain grows with ω_m) or relay (sign of
    /// ω_m). MRAS only; default normalised.
    #[arg(long, value_enum)]
    pub adaptation: Option<AdaptationArg>,
    /// Time constant of the K_e estimate [s] with --adaptation normalised: longer averages
    /// more noise, shorter follows faster changes; at least 100 sample times. MRAS only;
    /// default 0.5.
    #[arg(long, allow_hyphen_values = true)]
    pub tau_ke: Option<f64>,
    /// Time constant of the R_s estimate [s] with --adaptation normalised (over the samples
    /// where it adapts: |i_d| above --i-d-threshold). MRAS only; default 0.5.
    #[arg(long, allow_hyphen_values = true)]
    pub tau_rs: Option<f64>,
    /// Voltage hold of the log's source (MODEL.md §4): stator for a modulator, dq for a
    /// dq-held simulator. Default: the fit's with --params, else stator.
    #[arg(long, value_enum)]
    pub hold: Option<TrackHold>,
    /// The online estimator: the extended Kalman filter of R_s and K_e with their standard
    /// errors at every sample (`ekf`, the default), or the thesis' MRAS (`mras`, the
    /// reference, no uncertainty); docs/cli.md says why.
    #[arg(long, value_enum, default_value_t = EstimatorArg::Ekf)]
    pub estimator: EstimatorArg,
    /// With --estimator ekf: the standard deviation of the current noise [A] (each of id,
    /// iq); default: estimated from each log's second differences.
    #[arg(long, value_name = "A")]
    pub current_noise: Option<f64>,
    /// With --estimator ekf: how fast R_s may drift, its random walk's standard deviation
    /// after one second [Ω/√s]; default 3 % of the present estimate.
    #[arg(long, value_name = "OHM_PER_SQRT_S")]
    pub r_s_walk: Option<f64>,
    /// With --estimator ekf: how fast K_e may drift [V s/rad/√s]; default 0.2 % of the
    /// present estimate.
    #[arg(long, value_name = "VS_PER_SQRT_S")]
    pub k_e_walk: Option<f64>,
    /// Reference temperature T_0 [°C] of --r-s-t0 and --psi-f-t0: the winding temperature
    /// (copper) and the magnet temperature (NdFeB) are then given at every point, as `fit`
    /// derives them (MODEL.md §3), with intervals from --estimator ekf.
    #[arg(long, allow_hyphen_values = true)]
    pub t0: Option<f64>,
    /// Winding resistance at T_0 [Ω] (with --t0).
    #[arg(long)]
    pub r_s_t0: Option<f64>,
    /// Magnet flux ψ_f at T_0 [V s] (with --t0).
    #[arg(long)]
    pub psi_f_t0: Option<f64>,
    /// At most this many trajectory points per log in the JSON (evenly strided, the last
    /// kept).
    #[arg(long, default_value_t = 10_000)]
    pub max_points: usize,
    /// Write the JSON to this file ("-" for stdout, which suppresses the summary).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the observer plot (SVG) to this file: K_e (K_t) and R_s over time, with the
    /// truth when the log was written by `greybox simulate` (its truth JSON `LOG.truth.json`
    /// beside it).
    #[arg(long, value_name = "PATH.svg")]
    pub plot: Option<PathBuf>,
    /// Print nothing on stdout (the JSON and the plot are still written).
    #[arg(long, short = 'q')]
    pub quiet: bool,
    /// The log-reading flags (columns, units, window, limits).
    #[command(flatten)]
    pub columns: ColumnArgs,
}

/// The observer's adaptation law (`--adaptation`): `normalised`, `lyapunov`, `relay`.
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum AdaptationArg {
    Normalised,
    Lyapunov,
    Relay,
}

/// The online estimator (`--estimator`): `mras` or `ekf`.
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum EstimatorArg {
    Mras,
    Ekf,
}

/// The observer's voltage hold (`--hold`): `stator` or `dq`.
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum TrackHold {
    Stator,
    Dq,
}

/// Runs `greybox track`: the observer over every log, the summary lines on stdout, the JSON
/// and the plot where asked. Returns whether every run passed the filter's self-check
/// ([`Trajectory::consistent`]); each that did not is named in a warning on stderr.
///
/// # Errors
/// An output that cannot be written, an invalid observer setting (naming its flag), an
/// unreadable `--params` or log, an observer that fails on a log.
pub fn run_track(a: &TrackArgs) -> crate::Result<bool> {
    // Fail before the work, not after it, when the output cannot be written.
    let inputs: Vec<PathBuf> = a.logs.iter().chain(&a.params).cloned().collect();
    output::check_all(&[("--json", a.json.as_deref()), ("--plot", a.plot.as_deref())], &inputs)?;
    let thermal = thermal(a)?;
    let (runs, names) = track_logs(a)?;
    let mut staged = Staged::new();
    if let Some(plot) = &a.plot {
        super::plots::track_plot(&mut staged, plot, &runs)?;
    }
    let runs: Vec<(String, Trajectory)> = runs.into_iter().zip(names).map(|((_, _, t), n)| (n, t)).collect();
    let to_stdout = a.json.as_ref().is_some_and(|p| p.as_os_str() == "-");
    if !to_stdout && !a.quiet {
        for (name, tr) in &runs {
            super::output::stdout(&(report::summary_line(name, tr, a.pole_pairs, thermal.as_ref()) + "\n"))?;
        }
    }
    if let Some(path) = &a.json {
        output::write(
            &mut staged,
            path,
            &report::to_json(&runs, a.max_points, a.pole_pairs, thermal.as_ref()),
        )?;
    }
    staged.commit()?;
    let untrusted: Vec<&(String, Trajectory)> = runs.iter().filter(|(_, tr)| !tr.consistent()).collect();
    for (name, tr) in &untrusted {
        eprintln!(
            "warning: {name}: the Kalman filter's innovations are {} times as large as its model predicts \
             (their mean normalised square over the second half, halved; 1 when the model and the noise \
             level are right, at most {INNOVATION_RATIO_LIMIT} trusted): its estimates and intervals are not \
             to be trusted. Check --l-s and --l-q (or --params), --hold and the voltage the log gives, or \
             give the current noise with --current-noise; exit code 3",
            Ratio(tr.innovation_ratio.unwrap_or(f64::NAN))
        );
    }
    Ok(untrusted.is_empty())
}

/// The temperatures' reference of `--t0`, `--r-s-t0`, `--psi-f-t0` (MODEL.md §3), if
/// given.
///
/// # Errors
/// [`crate::Error::InvalidOption`] naming `--t0` for a reference value without it, and
/// those of [`ThermalReference::try_new`].
pub fn thermal(a: &TrackArgs) -> crate::Result<Option<ThermalReference>> {
    match (a.t0, a.r_s_t0, a.psi_f_t0) {
        (None, None, None) => Ok(None),
        (Some(t0), r, p) => ThermalReference::try_new(t0, r, p).map(Some).map_err(|e| match e {
            crate::Error::InvalidOption { reason, .. } => {
                crate::Error::InvalidOption { option: "t0".into(), reason }
            }
            e => e,
        }),
        (None, ..) => Err(crate::Error::InvalidOption {
            option: "t0".into(),
            reason: "--r-s-t0 and --psi-f-t0 are values at a reference temperature: give it with --t0".into(),
        }),
    }
}

/// One observer run: the log's path, its segment (`--split-gaps`, from 1) and the trajectory.
pub type TrackRun = (PathBuf, Option<usize>, Trajectory);

/// The observer of `greybox track` over every log of `a` (each segment of a log split at
/// its gaps on its own), with the run names the command prints (`LOG` or `LOG#k`), in the
/// order of the logs.
///
/// # Errors
/// An invalid observer setting (naming its flag), an unreadable `--params` or log, an
/// observer that fails on a log.
pub fn track_logs(a: &TrackArgs) -> crate::Result<(Vec<TrackRun>, Vec<String>)> {
    let (config, input) = config(a)?;
    let csv = CsvOptions { pole_pairs: Some(a.pole_pairs), ..a.columns.options() };
    let groups = a.columns.read_logs(&a.logs, &csv, false)?;
    let (mut runs, mut names) = (Vec::with_capacity(a.logs.len()), Vec::with_capacity(a.logs.len()));
    for (path, group) in a.logs.iter().zip(groups) {
        // With --split-gaps, each segment is tracked on its own: `LOG#1`, `LOG#2`, ….
        let one = group.len() == 1;
        for (k, log) in group.iter().enumerate() {
            // A fit from the reference voltage (--params) drives the observer with the voltage
            // its delay and advance apply, as it drove the fit.
            let applied = match input {
                VoltageInput::Terminal => None,
                _ => Some(applied_experiment(log, a.pole_pairs, input).map_err(|e| flag_error(e, path))?),
            };
            let log = applied.as_ref().unwrap_or(log);
            let trajectory = match a.estimator {
                EstimatorArg::Mras => track(log, &config),
                EstimatorArg::Ekf => {
                    track_kalman(log, &config, Some(noise(a, &config, log)?)).map_err(diverged)
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
fn diverged(e: crate::Error) -> crate::Error {
    match e {
        crate::Error::Numerical { context, reason } => crate::Error::Numerical {
            context,
            reason: format!(
                "{reason}: the filter diverged, its model does not fit this log (check --l-s and --l-q or \
                 --params, --hold and the voltage the log gives)"
            ),
        },
        e => e,
    }
}

/// The Kalman filter's noise model of the flags for `log`: `--current-noise` or the log's
/// own ([`current_noise`]), `--r-s-walk`, `--k-e-walk` or their defaults
/// ([`KalmanNoise::for_machine`]).
///
/// # Errors
/// A log without its currents (those of [`crate::pmsm::DqView::try_new`]).
fn noise(a: &TrackArgs, config: &MrasConfig, log: &crate::Experiment) -> crate::Result<KalmanNoise> {
    let sigma_i = match a.current_noise {
        Some(s) => s,
        None => {
            let v = crate::pmsm::DqView::try_new(log)?;
            current_noise(v.i_d(), v.i_q())
        }
    };
    let d = KalmanNoise::for_machine(sigma_i, config.r_s0, config.k_e0);
    if a.r_s_walk.is_none() && a.k_e_walk.is_none() {
        return Ok(d);
    }
    // A walk given is absolute: the other one's default taken at the start.
    let (q_r, q_k) = d.walks_at(config.r_s0, config.k_e0);
    Ok(KalmanNoise {
        q_r_s: a.r_s_walk.unwrap_or(q_r),
        q_k_e: a.k_e_walk.unwrap_or(q_k),
        relative: false,
        ..d
    })
}

/// Refuses a flag of the estimator not chosen: the MRAS's gains with the Kalman filter (the
/// default), the filter's noise with the MRAS.
///
/// # Errors
/// [`crate::Error::InvalidOption`] naming the first such flag.
fn other_estimators_flags(a: &TrackArgs) -> crate::Result<()> {
    let mras = [
        ("gamma-ke", a.gamma_ke.is_some()),
        ("gamma-rs", a.gamma_rs.is_some()),
        ("i-d-threshold", a.i_d_threshold.is_some()),
        ("observer-gain", a.observer_gain.is_some()),
        ("adaptation", a.adaptation.is_some()),
        ("tau-ke", a.tau_ke.is_some()),
        ("tau-rs", a.tau_rs.is_some()),
    ];
    let ekf = [
        ("current-noise", a.current_noise.is_some()),
        ("r-s-walk", a.r_s_walk.is_some()),
        ("k-e-walk", a.k_e_walk.is_some()),
    ];
    let (given, reason) = match a.estimator {
        EstimatorArg::Ekf => (
            mras.iter().find(|f| f.1),
            "is a setting of the MRAS: add --estimator mras, or drop it for the Kalman filter (the default), \
             whose settings are --current-noise, --r-s-walk and --k-e-walk",
        ),
        EstimatorArg::Mras => (
            ekf.iter().find(|f| f.1),
            "is a setting of the Kalman filter (--estimator ekf, the default): drop --estimator mras to use it",
        ),
    };
    match given {
        Some((flag, _)) => Err(crate::Error::InvalidOption { option: (*flag).into(), reason: reason.into() }),
        None => Ok(()),
    }
}

/// The observer's settings from the flags (and `--params`: its inductances, estimates, hold
/// and voltage input), validated before any log is read; errors name the flag.
fn config(a: &TrackArgs) -> crate::Result<(MrasConfig, VoltageInput)> {
    other_estimators_flags(a)?;
    let d = MrasConfig::default();
    let saved = match &a.params {
        None => None,
        Some(p) => {
            let text =
                std::fs::read_to_string(p).map_err(|source| crate::Error::Io { path: p.clone(), source })?;
            Some(SavedModel::from_json(&text, Some(a.pole_pairs), None)?)
        }
    };
    // The report's value of a parameter by name (SPM: r_s, l_s, k_e; IPM: r_s, l_d, l_q, k_e).
    let from_report = |name: &str| {
        let s = saved.as_ref()?;
        let i = s.kind.parameter_names().iter().position(|n| *n == name)?;
        s.theta.get(i).copied()
    };
    let l_s = a.l_s.or(from_report("l_s")).or(from_report("l_d")).ok_or_else(|| crate::Error::InvalidOption {
        option: "l-s".into(),
        reason: "the observer needs the stator inductance: give --l-s H (with --l-q: L_d) or --params REPORT.json of a fit"
            .into(),
    })?;
    let l_q = a.l_q.or(from_report("l_q"));
    let config = MrasConfig {
        n_p: a.pole_pairs,
        l_s,
        l_q,
        h: 1.0, // replaced by each log's sample time in `track`
        f: a.observer_gain.unwrap_or(d.f),
        gamma_ke: a.gamma_ke.unwrap_or(d.gamma_ke),
        gamma_rs: a.gamma_rs.unwrap_or(d.gamma_rs),
        i_d_threshold: a.i_d_threshold.unwrap_or(d.i_d_threshold),
        adaptation: match a.adaptation.unwrap_or(AdaptationArg::Normalised) {
            AdaptationArg::Normalised => Adaptation::Normalised,
            AdaptationArg::Lyapunov => Adaptation::Lyapunov,
            AdaptationArg::Relay => Adaptation::Relay,
        },
        tau_ke: a.tau_ke.unwrap_or(d.tau_ke),
        tau_rs: a.tau_rs.unwrap_or(d.tau_rs),
        k_e0: a.k_e0.or(from_report("k_e")).unwrap_or(0.0),
        r_s0: a.r_s0.or(from_report("r_s")).unwrap_or(0.0),
        hold: match a.hold {
            Some(TrackHold::Stator) => VoltageHold::Stator,
            Some(TrackHold::Dq) => VoltageHold::Dq,
            None => saved.as_ref().map_or(VoltageHold::Stator, |s| s.hold),
        },
    };
    config.validate().map_err(|e| flag_error(e, &PathBuf::new()))?;
    if saved.as_ref().is_some_and(|s| s.inverter.is_some()) {
        return Err(crate::Error::InvalidOption {
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
fn flag_error(e: crate::Error, log: &std::path::Path) -> crate::Error {
    match e {
        crate::Error::InvalidOption { option, reason } => {
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
            crate::Error::InvalidOption { option: flag.into(), reason }
        }
        // The observer's own failures name the sample, not the log.
        e @ (crate::Error::NonFinite { .. } | crate::Error::Numerical { .. })
            if !log.as_os_str().is_empty() =>
        {
            crate::Error::Numerical {
                context: format!("the observer over {}", log.display()),
                reason: e.to_string(),
            }
        }
        e => e,
    }
}

/// A ratio as a person reads it: three decimals below 1000, else `4.96e9`.
struct Ratio(f64);

impl std::fmt::Display for Ratio {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.abs() < 1000.0 { write!(f, "{:.3}", self.0) } else { write!(f, "{:.2e}", self.0) }
    }
}
