//! The mechanical fit: drive logs cut into windows ([`mechanics_windows`]), the torque from
//! the electrical model, and [`MechanicsModel`] fitted to all logs jointly, optionally with
//! the friction per log (its trend is how a gearbox announces wear).

use crate::data::{Channel, Experiment};
use crate::error::{Error, Result};
use crate::estimate::{FitResult, PemOptions, fit};
use crate::pmsm::model::mechanics::{Axis, MECHANICS_CHANNELS, MechanicsModel, MechanicsTerms};
use crate::pmsm::model::plant::MotorParameters;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Name of the load-torque channel \[N m\] a log may carry (subtracted when present in every
/// log).
pub const LOAD_TORQUE: &str = "t_load";

/// Fewest windows a log must give.
pub const MIN_WINDOWS: usize = 16;

/// Options of [`fit_mechanics`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MechanicsOptions {
    /// The electrical model whose torque `T_e = 1.5 n_p (ψ_f i_q + (L_d − L_q) i_d i_q)`
    /// drives the shaft (from an electrical fit, or `ψ_f = K_t / (1.5 n_p)` with
    /// `L_d = L_q` for a given `K_t`). `r_s` is not used.
    pub motor: MotorParameters,
    /// Window length \[s\] (rounded to whole samples, at least one).
    pub window: f64,
    /// Speed ω_c \[rad/s\] over which the Coulomb friction changes sign (`tanh(ω/ω_c)`);
    /// `None`: estimated, the lowest loss over \[10⁻⁴, 1\] × the logs' peak speed
    /// ([`COULOMB_SPEED_RANGE`]; a scan and a golden-section search on its logarithm).
    pub coulomb_speed: Option<f64>,
    /// Gravity and constant-load terms.
    pub terms: MechanicsTerms,
    /// The viscous and Coulomb friction (`b`, `t_c`) estimated per log; inertia and the
    /// loads shared.
    pub per_log_friction: bool,
    /// The prediction-error options (`per_experiment` is set by `per_log_friction`).
    pub pem: PemOptions,
    /// Relative standard error of the torque model's `K_t` (e.g. the electrical fit's
    /// `σ_k_t / k_t`); 0: taken as exact. Every mechanical parameter scales with `K_t`, so
    /// it adds `(value · this)²` to each variance ([`MechanicsFit::std_errors_with_torque`]).
    #[serde(default)]
    pub k_t_relative_se: f64,
    /// The axis the parameters describe: the shaft (default) or a linear axis it drives;
    /// the logs' speed and angle stay the shaft's \[rad/s, rad\], the load channel is a
    /// force \[N\] on a linear axis, and the Coulomb speed is in the axis' unit.
    #[serde(default, skip_serializing_if = "Axis::is_rotary")]
    pub axis: Axis,
}

impl MechanicsOptions {
    /// Defaults for `motor`: 10 ms windows, ω_c estimated, no gravity or constant load,
    /// shared friction.
    pub fn new(motor: MotorParameters) -> Self {
        Self {
            motor,
            window: 0.01,
            coulomb_speed: None,
            terms: MechanicsTerms::default(),
            per_log_friction: false,
            pem: PemOptions::default(),
            k_t_relative_se: 0.0,
            axis: Axis::Rotary,
        }
    }
}

/// A mechanical fit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MechanicsFit {
    /// The fit (`j`, `b`, `t_c`, then `mgl`, `t_0`; `b` and `t_c` per log with
    /// `per_log_friction`).
    pub fit: FitResult,
    /// Windows fitted (all logs).
    pub windows: usize,
    /// Window length \[s\].
    pub window: f64,
    /// `K_t` of the torque model \[N m/A\].
    pub k_t: f64,
    /// ω_c \[rad/s\] (on a linear axis v_c \[m/s\]).
    pub coulomb_speed: f64,
    /// Whether ω_c was estimated (its uncertainty is not in the intervals).
    #[serde(default)]
    pub coulomb_speed_estimated: bool,
    /// Whether a load-torque channel was subtracted.
    pub load_channel: bool,
    /// Relative standard error of `K_t` the torque model carries (0: exact).
    pub k_t_relative_se: f64,
    /// Per parameter of `fit` (same order), its standard error with the torque model's
    /// uncertainty: `√(σ² + (θ · σ_K_t/K_t)²)` \[its unit\]: every parameter scales with
    /// `K_t` (exact for surface magnets, whose torque is `K_t i_q`; for interior magnets an
    /// approximation that treats the reluctance torque's error as the magnet torque's).
    pub std_errors_with_torque: Vec<f64>,
    /// The axis the parameters describe ([`MechanicsOptions::axis`]).
    #[serde(default, skip_serializing_if = "Axis::is_rotary")]
    pub axis: Axis,
}

/// The window experiment of drive log `e` (channels `iq` \[A\], `id` for a salient motor,
/// `w_m` \[rad/s\], and
/// `theta_m` \[rad\] with a gravity term; [`LOAD_TORQUE`] \[N m\] when `load`): windows of
/// `m = round(window/h)` periods starting every `m + 1` samples (no shared ends), per
/// window `Δω = ω[k+m] − ω[k]` and the integrals of [`MECHANICS_CHANNELS`] (the torque held
/// over each period as the drive applies it: `h Σ T_e[k]`; the others by the trapezoid
/// rule). Its sample time is the window start spacing `(m + 1) h`; `x_1` holds `m h`. On a
/// linear [`Axis`] the speeds are the axis' `ω_m/r` \[m/s\] and the torque its force `r T_e`
/// \[N\] (`r` = [`Axis::radians_per_unit`]); the load channel is read as a force \[N\].
///
/// # Errors
/// [`Error::MissingChannel`] naming a channel; [`Error::InvalidOption`] (`window`) for a
/// window that is not positive or leaves fewer than [`MIN_WINDOWS`] windows, (`axis`) for a
/// linear axis whose lead is not positive and finite, (`gravity`) for a gravity term on it.
pub fn mechanics_windows(e: &Experiment, options: &MechanicsOptions, load: bool) -> Result<Experiment> {
    windows_at(e, options, load, options.coulomb_speed.unwrap_or(1.0))
}

/// [`mechanics_windows`] at the Coulomb speed `w_c` \[rad/s; m/s on a linear axis\].
fn windows_at(e: &Experiment, options: &MechanicsOptions, load: bool, w_c: f64) -> Result<Experiment> {
    options.axis.check(options.terms)?;
    let h = e.h();
    if !(options.window.is_finite() && options.window > 0.0) {
        return Err(Error::InvalidOption {
            option: "window".into(),
            reason: format!("{} s: the window must be positive", options.window),
        });
    }
    let m = ((options.window / h).round() as usize).max(1);
    // Windows `[a, a + m]` start every `m + 1` samples: no two share an end, so the speed
    // noise at the ends leaves the windows' residuals independent (white).
    let n_windows = e.len() / (m + 1);
    if n_windows < MIN_WINDOWS {
        return Err(Error::InvalidOption {
            option: "window".into(),
            reason: format!(
                "{}: {} windows of {m} samples; at least {MIN_WINDOWS} are needed: a shorter window",
                e.name(),
                n_windows
            ),
        });
    }
    let (i_q, w) = (e.channel("iq")?, e.channel("w_m")?);
    let zero = vec![0.0; e.len()];
    // A torque without reluctance (L_d = L_q: surface magnets, or a given K_t) reads no i_d.
    let i_d = if options.motor.salient() { e.channel("id")? } else { &zero };
    let theta = if options.terms.gravity { e.channel("theta_m")? } else { &zero };
    let t_l = if load { e.channel(LOAD_TORQUE)? } else { &zero };
    let trapezoid =
        |f: &dyn Fn(usize) -> f64, a: usize| h * (a..a + m).map(|k| 0.5 * (f(k) + f(k + 1))).sum::<f64>();
    // The axis' speed ω/r and force r T (r = 1 on the shaft: the same numbers to the bit).
    let r = options.axis.radians_per_unit();
    let mut cols: [Vec<f64>; 7] = Default::default();
    for j in 0..n_windows {
        let a = j * (m + 1);
        let row = [
            (w[a + m] - w[a]) / r,
            h * (a..a + m).map(|k| options.motor.torque(i_d[k], i_q[k]) * r).sum::<f64>(),
            trapezoid(&|k| w[k] / r, a),
            trapezoid(&|k| (w[k] / r / w_c).tanh(), a),
            trapezoid(&|k| theta[k].sin(), a),
            m as f64 * h,
            trapezoid(&|k| t_l[k], a),
        ];
        for (c, v) in cols.iter_mut().zip(row) {
            c.push(v);
        }
    }
    let units = match options.axis {
        Axis::Rotary => ["rad/s", "N m s", "rad", "s", "s", "s", "N m s"],
        Axis::Linear { .. } => ["m/s", "N s", "m", "s", "s", "s", "N s"],
    };
    let channels = MECHANICS_CHANNELS
        .into_iter()
        .zip(units)
        .zip(cols)
        .map(|((n, u), c)| Channel::new(n, u, c))
        .collect();
    Experiment::try_new(e.name(), (m + 1) as f64 * h, channels)
}

/// Fits the mechanics to drive logs (jointly): [`mechanics_windows`] of each, a linear
/// least-squares start (the model is linear in `1/J, B/J, T_c/J, …`), then the
/// prediction-error fit of [`MechanicsModel`]. The standard errors are those of
/// [`fit`] (batch means when the windows' residuals are not white); they are conditional on
/// the torque model: a relative error of `K_t` scales `J`, `B`, `T_c` and the loads alike.
///
/// # Errors
/// Those of [`mechanics_windows`] and [`fit`]; [`Error::InvalidOption`] (`coulomb_speed`)
/// for a ω_c that is not positive, or to be estimated from logs that never move; (`axis`)
/// for a linear axis whose lead is not positive and finite, or (`gravity`) with a gravity
/// term (a linear axis' weight is a constant force: `terms.constant`).
pub fn fit_mechanics(experiments: &[Experiment], options: &MechanicsOptions) -> Result<MechanicsFit> {
    if let Some(w_c) = options.coulomb_speed.filter(|w| !(w.is_finite() && *w > 0.0)) {
        return Err(Error::InvalidOption {
            option: "coulomb_speed".into(),
            reason: format!("{w_c} {} must be positive", options.axis.names().1),
        });
    }
    let load = !experiments.is_empty() && experiments.iter().all(|e| e.get(LOAD_TORQUE).is_some());
    let peak = experiments
        .iter()
        .filter_map(|e| e.channel("w_m").ok())
        .flat_map(|w| w.iter().map(|v| v.abs()))
        .fold(0.0, f64::max)
        / options.axis.radians_per_unit();
    let w_c = match options.coulomb_speed {
        Some(w_c) => w_c,
        None => estimated_coulomb_speed(experiments, options, load, peak)?,
    };
    let (windows, fitted) = fit_at(experiments, options, load, w_c)?;
    let warnings =
        fitted.warnings.iter().cloned().chain(super::friction::warnings(&fitted, peak, w_c, options.axis));
    let result = FitResult { warnings: warnings.collect(), ..fitted };
    Ok(MechanicsFit {
        windows: windows.iter().map(Experiment::len).sum(),
        window: windows.first().map_or(options.window, |w| w.channel("x_1").map_or(f64::NAN, |x| x[0])),
        k_t: options.motor.k_t(),
        coulomb_speed: w_c,
        coulomb_speed_estimated: options.coulomb_speed.is_none(),
        load_channel: load,
        k_t_relative_se: options.k_t_relative_se,
        std_errors_with_torque: result
            .parameters
            .iter()
            .map(|p| p.std_error.hypot(p.value * options.k_t_relative_se))
            .collect(),
        fit: result,
        axis: options.axis,
    })
}

/// The range of an estimated Coulomb speed, relative to the logs' peak speed.
pub const COULOMB_SPEED_RANGE: (f64, f64) = (1e-4, 1.0);

/// The Coulomb speed \[rad/s\] of the lowest loss over [`COULOMB_SPEED_RANGE`] × `peak`
/// (the logs' largest |ω| \[rad/s\]). The logs' own faults are named first, as they are:
/// a missing channel or a window too long (whatever ω_c), a speed that is zero throughout,
/// a torque the speed does not follow (the fit at the range's geometric middle); inside the
/// search a failed fit is a loss of ∞.
///
/// # Errors
/// Those of the windows and of the fit; [`Error::InvalidOption`] (`coulomb_speed`) for logs
/// that never move; [`Error::Numerical`] when no candidate fits.
fn estimated_coulomb_speed(
    experiments: &[Experiment],
    options: &MechanicsOptions,
    load: bool,
    peak: f64,
) -> Result<f64> {
    for e in experiments {
        windows_at(e, options, load, 1.0)?;
    }
    if !(peak > 0.0 && peak.is_finite()) {
        return Err(Error::InvalidOption {
            option: "coulomb_speed".into(),
            reason: "the logs' speed is zero throughout: no Coulomb speed can be estimated (give one)".into(),
        });
    }
    let range = (COULOMB_SPEED_RANGE.0 * peak, COULOMB_SPEED_RANGE.1 * peak);
    fit_at(experiments, options, load, (range.0 * range.1).sqrt())?;
    crate::pmsm::fit::search::golden_search(range, true, |w_c| {
        Ok(fit_at(experiments, options, load, w_c).map_or(f64::INFINITY, |(_, r)| r.fit.loss))
    })
}

/// The windows and the fit at the Coulomb speed `w_c` \[rad/s\].
fn fit_at(
    experiments: &[Experiment],
    options: &MechanicsOptions,
    load: bool,
    w_c: f64,
) -> Result<(Vec<Experiment>, FitResult)> {
    let windows =
        experiments.iter().map(|e| windows_at(e, options, load, w_c)).collect::<Result<Vec<_>>>()?;
    let start = least_squares_start(&windows, options.terms)?;
    let mut nominal = [start[0], start[1], start[2], 1.0, 1.0];
    for (j, v) in start.iter().enumerate().skip(3) {
        nominal[if j == 3 && options.terms.gravity { 3 } else { 4 }] = *v;
    }
    let model = MechanicsModel::on_axis(options.terms, nominal, options.axis);
    let mut pem = options.pem.clone();
    if options.per_log_friction && experiments.len() > 1 {
        let names = options.axis.names().0;
        pem.per_experiment = vec![names[1].0.into(), names[2].0.into()];
    }
    let fitted = fit(&model, &windows, &start, &pem)?;
    Ok((windows, fitted))
}

/// `[j, b, t_c, (mgl), (t_0)]` from the least squares of `Δω = c_T X_T − Σ c_i X_i`
/// (`c_T = 1/J`, `c_i = p_i/J`) over all windows, solved by SVD.
fn least_squares_start(windows: &[Experiment], terms: MechanicsTerms) -> Result<Vec<f64>> {
    let loss = terms.loss_channels();
    let (mut rows, mut rhs) = (Vec::new(), Vec::new());
    for e in windows {
        let ch: Vec<&[f64]> = MECHANICS_CHANNELS.iter().map(|c| e.channel(c)).collect::<Result<_>>()?;
        rows.extend((0..e.len()).map(|k| {
            let mut row = vec![ch[1][k] - ch[6][k]];
            row.extend(loss.iter().map(|&c| -ch[c][k]));
            row
        }));
        rhs.extend_from_slice(ch[0]);
    }
    let x = DMatrix::from_fn(rows.len(), 1 + loss.len(), |r, c| rows[r][c]);
    let c = x.svd(true, true).solve(&DVector::from_vec(rhs), 1e-14).map_err(|m| Error::Numerical {
        context: "mechanics start (least squares)".into(),
        reason: m.into(),
    })?;
    let j = 1.0 / c[0];
    if !(j > 0.0 && j.is_finite()) {
        return Err(Error::Numerical {
            context: "mechanics start (least squares)".into(),
            reason: format!(
                "the inertia comes out {j:e} kg m^2: the speed does not follow the torque (check the torque \
                 model's K_t and sign, the speed column and its unit)"
            ),
        });
    }
    Ok(std::iter::once(j).chain(c.iter().skip(1).map(|v| v * j)).collect())
}
