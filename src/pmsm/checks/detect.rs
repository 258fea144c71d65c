//! Detectors for the setup mistakes that otherwise give a confident wrong answer: a speed
//! in the wrong unit or frame, a surface-magnet model on a salient machine, a sample time
//! the model cannot resolve; and the conventions a fit assumes where the data cannot tell
//! (peak vs RMS, amplitude- vs power-invariant dq).
//!
//! The saliency check (and the pole-pair one of [`crate::pmsm::checks::pole_pairs`])
//! compares least-squares losses of the voltage equations (thesis 5.2.1). `n_p` enters only
//! through `ω_e = n_p ω_m`, so with the base columns `i`, `di/dt`, `ω_m i⊥`, `√(2/3) ω_m`
//! the regressors of any `n_p` are fixed combinations of them: one Gram matrix of the base
//! columns gives every candidate's loss exactly.

use crate::pmsm::model::interval::SQRT_2_3;
use crate::pmsm::model::kind::MotorKind;
use crate::report::eng::format_eng;
use multiversion::multiversion;
// Base columns of the scan: `i`, `di_d/dt` (d rows), `ω_m i_d` (q rows), `−ω_m i_q` (d rows),
// `di_q/dt` (q rows), `√(2/3) ω_m` (q rows), then the voltage. The salient regressors are
// combinations of them at any `n_p`, and so are the surface-magnet ones (`L_s` takes both
// derivative and both cross columns). The Gram comes from `scan_gram`, streamed.
use crate::error::{Error, Result};
use crate::estimate::{FitResult, Warning};
use crate::pmsm::checks::scan::BASE;
use crate::pmsm::log::Scale;
use crate::pmsm::log::longest_h;
use crate::pmsm::log::signals::DqView;
use nalgebra::{DMatrix, DVector};

/// Loss ratio (surface-magnet over salient regression) from which a log is salient for
/// sure (noise-free salient logs give 10⁴–10⁷; noisy ones a few).
pub const SALIENT_CERTAIN: f64 = 100.0;
/// Loss ratio from which a warning says the log may be salient.
pub const SALIENT_LIKELY: f64 = 2.0;
/// Relative inductance difference that counts as salient.
pub const SALIENCY: f64 = 0.1;
/// Relative mismatch of `dθ_m/dt` and `w_m` beyond which the speed check reports.
pub const SPEED_MISMATCH: f64 = 0.05;

/// Least-squares loss `½ min‖y − Φθ‖²` and θ (model order of `kind`) at `n_p` from the
/// Gram matrix of [`crate::pmsm::checks::scan::scan_gram`].
pub(super) fn loss_at(g: &DMatrix<f64>, kind: MotorKind, n_p: u32) -> Option<(f64, DVector<f64>)> {
    loss_at_factor(g, kind, f64::from(n_p))
}

/// [`loss_at`] with any factor `np` on the speed in the rotation terms (`ω_e = np ω_m`):
/// a pole-pair number times a speed column's scale.
pub(crate) fn loss_at_factor(g: &DMatrix<f64>, kind: MotorKind, np: f64) -> Option<(f64, DVector<f64>)> {
    let t = to_base(kind, np);
    let gcc = g.view((0, 0), (BASE, BASE));
    let gcy = g.view((0, BASE), (BASE, 1));
    let a = t.transpose() * gcc * &t;
    let b = t.transpose() * gcy;
    let theta = a.clone().cholesky()?.solve(&b);
    let loss = 0.5 * (g[(BASE, BASE)] - (b.transpose() * &theta)[(0, 0)]);
    Some((loss.max(0.0), theta.column(0).into_owned()))
}

/// The map `T` (`BASE × n_θ`) from the parameters of `kind` (MODEL.md §2 order) to the
/// scan's base columns at the rotation factor `np` (`ω_e = np ω_m`): the regressors are
/// `C T`.
pub(crate) fn to_base(kind: MotorKind, np: f64) -> DMatrix<f64> {
    match kind {
        MotorKind::Spm => DMatrix::from_row_slice(
            BASE,
            3,
            &[1.0, 0., 0., 0., 1.0, 0., 0., np, 0., 0., np, 0., 0., 1.0, 0., 0., 0., 1.0],
        ),
        MotorKind::Ipm => DMatrix::from_row_slice(
            BASE,
            4,
            &[
                1.0, 0., 0., 0., 0., 1.0, 0., 0., 0., np, 0., 0., 0., 0., np, 0., 0., 0., 1.0, 0., 0., 0.,
                0., 1.0,
            ],
        ),
    }
}

/// The structure check before a surface-magnet fit: the salient regression lowers the
/// loss by a factor `ratio` with `L_d`, `L_q` more than [`SALIENCY`] apart. From
/// [`SALIENT_CERTAIN`] on the log is salient (an error); from [`SALIENT_LIKELY`] on a warning
/// says so (an unmodelled voltage error, such as dead time, can look salient too). Not run
/// with the inverter model, whose error the regression does not contain. `g` is the
/// [`crate::pmsm::checks::scan::scan_gram`] of the logs.
///
/// # Errors
/// [`Error::InvalidOption`] (`model`) naming both inductances and the loss ratio.
pub(crate) fn check_structure(g: &DMatrix<f64>, n_p: u32, kind: MotorKind) -> Result<Option<Warning>> {
    if kind != MotorKind::Spm {
        return Ok(None);
    }
    let (Some((ls, _)), Some((li, th))) = (loss_at(g, MotorKind::Spm, n_p), loss_at(g, MotorKind::Ipm, n_p))
    else {
        return Ok(None);
    };
    let (l_d, l_q) = (th[1], th[2]);
    let saliency = (l_d - l_q).abs() / l_d.abs().max(l_q.abs());
    let ratio = ls / li;
    let what = format!(
        "a regression with L_d = {l_d:.4e} H and L_q = {l_q:.4e} H ({:.0} % apart) lowers the loss {ratio:.1} times",
        100.0 * saliency
    );
    if saliency <= SALIENCY || ratio < SALIENT_LIKELY {
        Ok(None)
    } else if ratio >= SALIENT_CERTAIN {
        Err(Error::InvalidOption {
            option: "model".into(),
            reason: format!("the log is salient: {what}; fit it with --model ipm"),
        })
    } else {
        Ok(Some(Warning::untrusted(
            "salient",
            format!(
                "{what}: the machine may be salient (--model ipm), or the voltage has an error the model lacks \
                 (dead time: --dead-time estimate)"
            ),
        )))
    }
}

/// The warnings of a PMSM fit from its logs: a speed unit or frame mistake, and the assumed
/// scaling of columns read as `read` (`[currents, voltages]`; checks that cannot run are
/// skipped).
pub(crate) fn warnings(views: &[DqView<'_>], n_p: u32, fit: &FitResult, read: [Scale; 2]) -> Vec<Warning> {
    let mut out = Vec::new();
    out.extend(speed_check(views, n_p));
    out.extend(sample_time_check(views, n_p, fit));
    out.push(scaling_notice(fit, read));
    out
}

/// The warnings of a steady-state fit: the speed check where the angle does not alias (a
/// slow log's angle turns by more than π between samples and cannot be compared), and the
/// assumed scaling of columns read as `read` (`[currents, voltages]`).
pub(crate) fn steady_warnings(
    views: &[DqView<'_>],
    n_p: u32,
    fit: &FitResult,
    read: [Scale; 2],
) -> Vec<Warning> {
    let mut out = Vec::new();
    if max_turn(views, n_p) < std::f64::consts::PI {
        out.extend(speed_check(views, n_p));
    }
    out.push(scaling_notice(fit, read));
    out
}

/// The most electrical radians the rotor turns within one sample in any of the logs at
/// `n_p` pole pairs, `max_e n_p h_e max|w_m|` \[rad\].
pub(crate) fn max_turn(views: &[DqView<'_>], n_p: u32) -> f64 {
    views
        .iter()
        .map(|v| f64::from(n_p) * v.h() * v.w_m().iter().fold(0.0f64, |m, x| m.max(x.abs())))
        .fold(0.0, f64::max)
}

/// The sums `(Σ dθ·ω/h, Σ ω²)` of [`speed_check`] continued over one log: per interval the
/// angle's step `dθ` (wrapped to ±π) and the mean speed ω, where |ω| exceeds 5 % of the
/// log's peak; compiled for AVX2 as well (the rounding inline, not a library call).
#[multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
pub(super) fn speed_sums((mut num, mut den): (f64, f64), th: &[f64], w: &[f64], h: f64) -> (f64, f64) {
    let peak = w.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for ((t, w), (t1, w1)) in th.iter().zip(w).zip(th.iter().zip(w).skip(1)) {
        let d = t1 - t;
        let d = d - std::f64::consts::TAU * (d / std::f64::consts::TAU).round();
        let wm = 0.5 * (w + w1);
        if wm.abs() > 0.05 * peak {
            num += d / h * wm;
            den += wm * wm;
        }
    }
    (num, den)
}

/// Compares `dθ_m/dt` with `w_m` (when `theta_m` is logged) and names the likely mistake
/// when they differ by a known factor.
fn speed_check(views: &[DqView<'_>], n_p: u32) -> Option<Warning> {
    let (mut num, mut den) = (0.0, 0.0);
    for v in views {
        let Some(th) = v.theta_m() else { continue };
        (num, den) = speed_sums((num, den), th, v.w_m(), v.h());
    }
    let r = num / den;
    if !r.is_finite() || (r - 1.0).abs() <= SPEED_MISMATCH {
        return None;
    }
    let np = f64::from(n_p);
    let rpm = std::f64::consts::PI / 30.0;
    let deg = std::f64::consts::PI / 180.0;
    let candidates = [
        (
            np,
            "θ_m turns n_p times faster than w_m says: the angle is electrical while the speed is mechanical (log both in one frame)",
        ),
        (
            1.0 / np,
            "w_m is n_p times faster than dθ_m/dt: the speed is electrical (--speed-frame electrical)",
        ),
        (rpm, "w_m is 30/π times faster than dθ_m/dt: the speed is in rpm (--speed-unit rpm)"),
        (rpm / np, "the speed is electrical and in rpm (--speed-frame electrical --speed-unit rpm)"),
        (
            1.0 / rpm,
            "w_m is 30/π times slower than dθ_m/dt: the speed is in rad/s, not rpm (drop --speed-unit rpm)",
        ),
        (1.0 / deg, "dθ_m/dt is 180/π times w_m: the angle is in degrees (--angle-unit deg)"),
        (1e-3, "dθ_m/dt is 1000 times smaller than w_m: the time column is in milliseconds"),
        (1e-6, "dθ_m/dt is 10⁶ times smaller than w_m: the time column is in microseconds"),
    ];
    let (_, why) = candidates
        .iter()
        .min_by(|a, b| (r / a.0).ln().abs().total_cmp(&(r / b.0).ln().abs()))
        .filter(|(f, _)| (r / f - 1.0).abs() <= SPEED_MISMATCH)
        .copied()
        .unwrap_or((r, "no known unit or frame factor explains it"));
    Some(Warning::untrusted("speed_unit", format!("dθ_m/dt is {r:.4} times w_m (expected 1): {why}")))
}

/// Largest sample time, in electrical time constants `L/R`, at which the current's
/// dynamics are still seen (beyond it the current settles within one sample).
pub const MAX_H_OVER_TAU: f64 = 5.0;

/// A sample time the model cannot resolve: `h` beyond [`MAX_H_OVER_TAU`] electrical time
/// constants (the inductances then act through the rotation terms alone), or the rotor
/// turning π electrical radians or more within one sample at the log's top speed (the
/// angle aliases). Most often a time column in milliseconds read as seconds: the warning
/// says what `--time-unit ms` would give.
fn sample_time_check(views: &[DqView<'_>], n_p: u32, fit: &FitResult) -> Option<Warning> {
    let r = fit.parameter("r_s")?.value;
    sample_time_problem(views, n_p, r, crate::pmsm::model::kind::smallest_inductance(fit))
        .map(|why| Warning::untrusted("sample_time", why))
}

/// Why the logs' sample time is one the model cannot resolve with resistance `r` \[Ω\] and
/// smallest inductance `l` \[H\] ([`sample_time_check`]'s conditions), or `None`: the
/// facts of [`sample_time_facts`], the question whether the time column is in ms, and the
/// steady-state equations for slow telemetry (whose point-sampled voltage leaves the dynamic
/// fit's `L/R` meaningless: on a set-aside log cut to 250 Hz it read 0.43 ms for 13 ms).
pub(crate) fn sample_time_problem(views: &[DqView<'_>], n_p: u32, r: f64, l: f64) -> Option<String> {
    let h = longest_h(views);
    sample_time_facts(views, n_p, r, l).map(|facts| {
        format!(
            "{facts}. A time column in milliseconds? (--time-unit ms gives h = {:e} s). Slow telemetry of a \
             faster drive? (--model spm-steady or ipm-steady fits the steady-state equations)",
            h * 1e-3
        )
    })
}

/// The facts of [`sample_time_problem`] alone: the sample time in electrical time
/// constants and the rotor's turn per sample, when the model cannot resolve them.
pub(crate) fn sample_time_facts(views: &[DqView<'_>], n_p: u32, r: f64, l: f64) -> Option<String> {
    let h = longest_h(views);
    let w = views.iter().map(|v| v.w_m().iter().fold(0.0f64, |m, x| m.max(x.abs()))).fold(0.0, f64::max);
    let (tau, turn) = (l / r, f64::from(n_p) * w * h);
    let slow = tau.is_finite() && tau > 0.0 && h > MAX_H_OVER_TAU * tau;
    if !slow && turn < std::f64::consts::PI {
        return None;
    }
    Some(format!(
        "h = {h:e} s is {:.1} electrical time constants L/R ({tau:.3e} s) and the rotor turns up to {turn:.2} \
         electrical rad in one sample: the model cannot resolve the currents at this rate",
        h / tau
    ))
}

/// What the estimates would be under the conventions the data cannot tell apart, for
/// columns read as `read` (`[currents, voltages]`): the voltage equations are homogeneous
/// in the current, so currents scaled by `c` give `r_s`, the inductances `÷ c` and `k_e`
/// unchanged; voltages scaled by `c` give `r_s`, the inductances and `k_e` `× c` (MODEL.md
/// §1). With a column read as RMS (multiplied by `√2`), the alternative offered is that it
/// held peak values.
fn scaling_notice(fit: &FitResult, [current, voltage]: [Scale; 2]) -> Warning {
    let v = |n: &str| fit.parameter(n).map(|p| p.value);
    let r = v("r_s").unwrap_or(f64::NAN);
    let k = v("k_e").unwrap_or(f64::NAN);
    let s2 = std::f64::consts::SQRT_2;
    let ohm = |x: f64| format_eng(x, "ohm", 5);
    let read = match (current, voltage) {
        (Scale::Peak, Scale::Peak) => {
            "currents and voltages read as amplitude-invariant dq peak values".to_string()
        }
        (c, u) => {
            let as_read = |s: Scale, flag: &str| match s {
                Scale::Peak => "peak values".to_string(),
                Scale::Rms => format!("RMS values (multiplied by √2 on reading, {flag} rms)"),
            };
            format!(
                "currents read as {} and voltages as {}, amplitude-invariant dq",
                as_read(c, "--current-scale"),
                as_read(u, "--voltage-scale")
            )
        }
    };
    let currents = match current {
        Scale::Peak => format!("If the currents were RMS: r_s {} and the inductances ÷√2", ohm(r / s2)),
        Scale::Rms => {
            format!("If the currents were peak values, not RMS: r_s {} and the inductances ×√2", ohm(r * s2))
        }
    };
    let voltages = match voltage {
        Scale::Peak => format!(
            "if the voltages were RMS: r_s {}, inductances and k_e {} ×√2",
            ohm(r * s2),
            format_eng(k * s2, "V s/rad", 5)
        ),
        Scale::Rms => format!(
            "if the voltages were peak values, not RMS: r_s {}, inductances and k_e {} ÷√2",
            ohm(r / s2),
            format_eng(k / s2, "V s/rad", 5)
        ),
    };
    Warning::notice(
        "scaling_assumed",
        format!(
            "{read} (MODEL.md §1); the data cannot tell. {currents}; {voltages}; if the dq transform was \
             power-invariant: k_e {} (÷√(3/2)), r_s and inductances unchanged",
            format_eng(k * SQRT_2_3, "V s/rad", 5)
        ),
    )
}
