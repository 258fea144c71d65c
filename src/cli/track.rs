//! `greybox track`: the MRAS observer (thesis 5.1) over each log, its final estimates and
//! their trajectory.

use super::args::ColumnArgs;
use super::output;
use crate::app::{Estimator, KalmanSettings, MrasSettings, TrackRequest, track_logs};
use crate::data::Staged;
use crate::online::{Adaptation, INNOVATION_RATIO_LIMIT, Trajectory};
use crate::pmsm::VoltageHold;
use clap::{Args, ValueEnum};
use std::path::PathBuf;

mod report;

/// Arguments of `greybox track`.
///
/// JSON shape (`--json`): one log gives `{"final": {"k_e", "k_t", "r_s", "innovation_ratio",
/// "trusted"}, "trajectory": {"t": [], "k_e": [], "r_s": []}}` (with `--estimator ekf` also
/// `k_e_se`, `k_t_se`, `r_s_se` in `final` and `k_e_se`, `r_s_se` in `trajectory`: standard
/// errors);
/// several logs give `{"logs": [{"log": PATH, "final": …, "trajectory": …}, …]}` in the
/// order given (PATH as given on the command line). Non-finite numbers are written as `null`.
#[derive(Args, Debug)]
#[command(
    after_help = "JSON (--json): one log gives {\"final\": {\"k_e\", \"k_t\", \"r_s\", \"innovation_ratio\", \
\"trusted\"}, \"trajectory\": {\"t\": [...], \"k_e\": [...], \"r_s\": [...]}}; several logs give {\"logs\": [{\"log\": PATH, \"final\": ..., \
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
/// and the plot where asked. Returns whether every run passed its self-check
/// ([`Trajectory::consistent`]); each that did not is named in a warning on stderr.
///
/// # Errors
/// An output that cannot be written, an invalid observer setting (naming its flag), an
/// unreadable `--params` or log, an observer that fails on a log.
pub fn run_track(a: &TrackArgs) -> crate::Result<bool> {
    // Fail before the work, not after it, when the output cannot be written.
    let inputs: Vec<PathBuf> = a.logs.iter().chain(&a.params).cloned().collect();
    output::check_all(&[("--json", a.json.as_deref()), ("--plot", a.plot.as_deref())], &inputs)?;
    let request = TrackRequest::from(a);
    let thermal = request.thermal()?;
    let (runs, names) = track_logs(&a.logs, &request)?;
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
        // The filter's trajectory carries standard errors, the MRAS's none.
        let (what, how, flag) = if tr.final_se().is_some() {
            (
                "the Kalman filter's innovations are",
                "their mean normalised square over the second half, halved",
                ", or give the current noise with --current-noise",
            )
        } else {
            (
                "the MRAS's one-step prediction errors (from the measured current at its running estimates) are",
                "their errors' mean square over the second half over 4σ², σ the current noise the log shows",
                "; or the parameters changed faster than its time constants (--tau-ke, --tau-rs) follow, \
                 which the Kalman filter (--estimator ekf) allows for",
            )
        };
        eprintln!(
            "warning: {name}: {what} {} times as large as the model predicts ({how}; 1 when the model \
             and the noise level are right, at most {INNOVATION_RATIO_LIMIT} trusted): its estimates are not \
             to be trusted. Check --l-s and --l-q (or --params), --hold and the voltage the log gives{flag}; \
             exit code 3",
            Ratio(tr.innovation_ratio.unwrap_or(f64::NAN))
        );
    }
    Ok(untrusted.is_empty())
}

impl From<&TrackArgs> for TrackRequest {
    /// The request of the flags (`--json`, `--plot`, `--max-points` and `--quiet` are the
    /// command line's outputs, not the request's).
    fn from(a: &TrackArgs) -> Self {
        TrackRequest {
            pole_pairs: a.pole_pairs,
            reading: a.columns.reading(),
            l_s: a.l_s,
            l_q: a.l_q,
            params: a.params.clone(),
            k_e0: a.k_e0,
            r_s0: a.r_s0,
            hold: a.hold.map(|h| match h {
                TrackHold::Stator => VoltageHold::Stator,
                TrackHold::Dq => VoltageHold::Dq,
            }),
            estimator: match a.estimator {
                EstimatorArg::Mras => Estimator::Mras,
                EstimatorArg::Ekf => Estimator::Ekf,
            },
            mras: MrasSettings {
                gamma_ke: a.gamma_ke,
                gamma_rs: a.gamma_rs,
                i_d_threshold: a.i_d_threshold,
                observer_gain: a.observer_gain,
                adaptation: a.adaptation.map(|x| match x {
                    AdaptationArg::Normalised => Adaptation::Normalised,
                    AdaptationArg::Lyapunov => Adaptation::Lyapunov,
                    AdaptationArg::Relay => Adaptation::Relay,
                }),
                tau_ke: a.tau_ke,
                tau_rs: a.tau_rs,
            },
            kalman: KalmanSettings {
                current_noise: a.current_noise,
                r_s_walk: a.r_s_walk,
                k_e_walk: a.k_e_walk,
            },
            t0: a.t0,
            r_s_t0: a.r_s_t0,
            psi_f_t0: a.psi_f_t0,
        }
    }
}

/// A ratio as a person reads it: three decimals below 1000, else `4.96e9`.
struct Ratio(f64);

impl std::fmt::Display for Ratio {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.abs() < 1000.0 { write!(f, "{:.3}", self.0) } else { write!(f, "{:.2e}", self.0) }
    }
}
