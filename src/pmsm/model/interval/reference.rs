//! The intervals of a log driven by the controller's voltage *reference* (delay, angle
//! advance, stator hold by the modulator), the choice between it and the terminal voltage,
//! and the period-mean voltage either applies (MODEL.md §4, "Reference versus actual
//! voltage").

use super::dq::motion;
use super::{C64, Interval, VoltageHold, VoltageInput, intervals, mean_speed, stator_hold_start};
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::pmsm::log::signals::{DqSignals, DqView};
use std::borrow::Cow;

/// The intervals `k = 0..N−2` of a log driven by the voltage *reference* (channels
/// `ud_ref`, `uq_ref`): the reference computed at `t_j`, `j = k − d`, in the dq frame of
/// `θ_e(t_j)`, advanced by `a ω_e(t_j) h`, held in the stator frame; at the start of
/// interval k the frame has turned by `Σ_{i=j}^{k−1} φ_i` (interval-mean speeds), so
/// `u₀ = u_ref[j] e^{j(a φ(t_j) − Σ φ_i)}` (with d = 1, a = 1.5 at constant speed:
/// `u_ref[k−1] e^{jφ/2}`, MODEL.md §4). Intervals `k < d` use the first reference.
///
/// # Errors
/// [`Error::MissingChannel`] when the log has no `ud_ref`/`uq_ref`; [`Error::InvalidOption`]
/// for a non-finite advance or a delay not shorter than the log.
pub fn reference_intervals(
    v: &DqView<'_>,
    n_p: u32,
    delay: usize,
    advance: f64,
    speed_pll: Option<f64>,
) -> Result<Vec<Interval>> {
    let u0 = reference_start_voltages(v, n_p, delay, advance, speed_pll)?;
    Ok(motion(v, n_p).zip(u0).map(|(iv, u0)| Interval { u0, ..iv }).collect())
}

/// The start-of-period voltages `u₀` of [`reference_intervals`] alone (its errors), length
/// N − 1 \[V\]: the interval rotations are not formed.
fn reference_start_voltages(
    v: &DqView<'_>,
    n_p: u32,
    delay: usize,
    advance: f64,
    speed_pll: Option<f64>,
) -> Result<Vec<C64>> {
    let (ud, uq, w_adv) = reference_channels(v, n_p, delay, advance, speed_pll)?;
    let (h, np) = (v.h(), f64::from(n_p));
    // φ_k = ω_e h of each interval, as `motion` forms ω_e.
    let phis: Vec<f64> = v.w_m().windows(2).map(|w| np * mean_speed(w) * h).collect();
    Ok((0..phis.len())
        .map(|k| {
            let j = k.saturating_sub(delay);
            let turned: f64 = phis[j..k].iter().sum();
            let angle = advance * w_adv[j] * h - turned;
            C64::new(ud[j], uq[j]) * C64::new(angle.cos(), angle.sin())
        })
        .collect())
}

/// The reference `ud_ref, uq_ref` \[V\] of a log driven by it, checked against its delay
/// and advance, with the electrical speed \[rad/s\] the controller advances each sample's
/// reference by: the logged one, or that of a phase-locked loop of bandwidth `speed_pll` on
/// `theta_m` ([`speed_pll_estimate`]); length N each.
///
/// # Errors
/// [`Error::MissingChannel`] when the log has no `ud_ref`/`uq_ref` (or no `theta_m` for the
/// loop); [`Error::InvalidOption`] for a non-finite advance or a delay not shorter than
/// the log.
pub(crate) fn reference_channels<'a>(
    v: &DqView<'a>,
    n_p: u32,
    delay: usize,
    advance: f64,
    speed_pll: Option<f64>,
) -> Result<(&'a [f64], &'a [f64], Vec<f64>)> {
    let e = v.experiment();
    let (ud, uq) = (e.channel(crate::pmsm::channel::U_D_REF)?, e.channel(crate::pmsm::channel::U_Q_REF)?);
    if !advance.is_finite() || delay + 1 >= v.len() {
        return Err(Error::InvalidOption {
            option: "voltage".into(),
            reason: format!("reference delay {delay} and advance {advance} for a log of {} samples", v.len()),
        });
    }
    let np = f64::from(n_p);
    let w_adv: Vec<f64> = match speed_pll {
        None => v.w_m().iter().map(|w| np * w).collect(),
        Some(a) => speed_pll_estimate(e.channel(crate::pmsm::channel::THETA_M)?, v.w_m(), n_p, v.h(), a),
    };
    Ok((ud, uq, w_adv))
}

/// The intervals of a log for the given hold and voltage input: [`intervals`] for the
/// terminal voltage, [`reference_intervals`] for the reference (which a modulator holds in
/// the stator frame).
///
/// # Errors
/// Those of [`reference_intervals`]; [`Error::InvalidOption`] for a reference voltage with
/// the dq hold.
pub fn model_intervals(
    v: &DqView<'_>,
    n_p: u32,
    hold: VoltageHold,
    input: VoltageInput,
) -> Result<Vec<Interval>> {
    match input {
        VoltageInput::Terminal => Ok(intervals(v, n_p, hold)?.collect()),
        VoltageInput::Reference { .. } => {
            let u0 = model_start_voltages(v, n_p, hold, input)?;
            Ok(motion(v, n_p).zip(u0).map(|(iv, u0)| Interval { u0, ..iv }).collect())
        }
    }
}

/// The start-of-period voltages `u₀` of [`model_intervals`] alone (its errors), length
/// N − 1 \[V\]: for a caller that forms the intervals' rotations itself.
pub(crate) fn model_start_voltages(
    v: &DqView<'_>,
    n_p: u32,
    hold: VoltageHold,
    input: VoltageInput,
) -> Result<Vec<C64>> {
    match input {
        VoltageInput::Terminal => Ok(intervals(v, n_p, hold)?.map(|iv| iv.u0).collect()),
        VoltageInput::Reference { .. } if hold == VoltageHold::Dq => Err(Error::InvalidOption {
            option: "hold".into(),
            reason: "a reference voltage is applied by a modulator, which holds it in the stator frame"
                .into(),
        }),
        VoltageInput::Reference { delay, advance, speed_pll } => {
            reference_start_voltages(v, n_p, delay, advance, speed_pll)
        }
    }
}

/// The dq voltage applied over each interval as its period mean \[V\], `(u_d, u_q)` of
/// length N (the last sample repeats the last interval): the terminal voltage itself, or
/// the reference after its delay and advance (`mean = u₀ (1 − e^{−jφ})/(jφ)`, the inverse
/// of [`stator_hold_start`]). This is what the linear least-squares start regresses on.
///
/// # Errors
/// Those of [`model_intervals`].
pub fn applied_voltage(v: &DqView<'_>, n_p: u32, input: VoltageInput) -> Result<(Vec<f64>, Vec<f64>)> {
    if input == VoltageInput::Terminal {
        let (u_d, u_q) = v.terminal_voltage()?;
        return Ok((u_d.to_vec(), u_q.to_vec()));
    }
    let ivs = model_intervals(v, n_p, VoltageHold::Stator, input)?;
    let h = v.h();
    let mut mean: Vec<C64> =
        ivs.iter().map(|iv| iv.u0 / stator_hold_start(C64::new(1.0, 0.0), iv.w_e * h)).collect();
    mean.push(mean.last().copied().unwrap_or_default());
    Ok((mean.iter().map(|u| u.re).collect(), mean.iter().map(|u| u.im).collect()))
}

/// A pair of dq signals `(d, q)`, borrowed from a log or computed.
pub(crate) type DqPair<'a> = (Cow<'a, [f64]>, Cow<'a, [f64]>);

/// The voltage a regression on the voltage equations reads, `(u_d, u_q)` \[V\] of length N:
/// [`applied_voltage`], borrowing the terminal voltage instead of copying it.
///
/// # Errors
/// Those of [`DqView::terminal_voltage`] and [`applied_voltage`].
pub(crate) fn driving_voltage<'a>(v: &DqView<'a>, n_p: u32, input: VoltageInput) -> Result<DqPair<'a>> {
    if input == VoltageInput::Terminal {
        let (u_d, u_q) = v.terminal_voltage()?;
        return Ok((Cow::Borrowed(u_d), Cow::Borrowed(u_q)));
    }
    let (u_d, u_q) = applied_voltage(v, n_p, input)?;
    Ok((Cow::Owned(u_d), Cow::Owned(u_q)))
}

/// Electrical speed \[rad/s\] at every sample as a phase-locked loop of bandwidth `alpha`
/// \[rad/s\] estimates it from the mechanical angle `theta_m` (a drive's usual speed
/// estimate; critically damped, started at the logged speed), length N.
pub fn speed_pll_estimate(theta_m: &[f64], w_m: &[f64], n_p: u32, h: f64, alpha: f64) -> Vec<f64> {
    let np = f64::from(n_p);
    let (mut theta, mut w) =
        (np * theta_m.first().copied().unwrap_or(0.0), np * w_m.first().copied().unwrap_or(0.0));
    theta_m
        .iter()
        .map(|&t| {
            let out = w;
            let d = np * t - theta;
            let err = d.sin().atan2(d.cos());
            w += h * alpha * alpha * err;
            theta += h * (w + 2.0 * alpha * err);
            out
        })
        .collect()
}

/// The frame a sensored controller transforms its voltage reference with: its rotor-angle
/// estimate `θ̂_c` \[rad, electrical\] and the frame's speed `ω_c` \[rad/s, electrical\] it
/// advances the reference by, at every sample (length N each), from a phase-locked loop of
/// bandwidth `alpha` \[rad/s\] on the logged angle `theta_m` \[rad, mechanical\], started
/// at the logged angle and speed `w_m` \[rad/s\]: `e = θ_e − θ̂_c` (wrapped),
/// `ω_c = ω̂ + 2 α e`, `θ̂_c ← θ̂_c + h ω_c`, `ω̂ ← ω̂ + h α² e` (critically damped; the
/// sensored speed and flux observer of motulator, `drive/control/_sm_observers.py`,
/// `k_θ = 2 α_o`, `k_ω = α_o²`; Hinkkanen et al., *IEEE Trans. Ind. Appl.* 54(6), 2018).
/// [`speed_pll_estimate`] is the same loop's `ω̂`, for a controller that transforms with the
/// logged angle.
pub fn controller_frame(theta_m: &[f64], w_m: &[f64], n_p: u32, h: f64, alpha: f64) -> (Vec<f64>, Vec<f64>) {
    let np = f64::from(n_p);
    let (mut theta, mut w) =
        (np * theta_m.first().copied().unwrap_or(0.0), np * w_m.first().copied().unwrap_or(0.0));
    theta_m
        .iter()
        .map(|&t| {
            let d = np * t - theta;
            let err = d.sin().atan2(d.cos());
            let w_c = w + 2.0 * alpha * err;
            let out = (theta, w_c);
            theta += h * w_c;
            w += h * alpha * alpha * err;
            out
        })
        .unzip()
}

/// The experiment with its `ud, uq` replaced by the applied period-mean voltage of
/// [`applied_voltage`] (for a regression on the voltage equations).
///
/// # Errors
/// Those of [`DqView::try_new`] and [`applied_voltage`].
pub fn applied_experiment(e: &Experiment, n_p: u32, input: VoltageInput) -> Result<Experiment> {
    let v = DqView::try_new(e)?;
    let (u_d, u_q) = applied_voltage(&v, n_p, input)?;
    Ok(DqSignals { u_d, u_q, ..v.to_signals() }.into_experiment(e.name(), e.h())?.with_t0(e.t0()))
}
