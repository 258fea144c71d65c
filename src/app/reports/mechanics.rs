//! Inertia, viscous and Coulomb friction, gravity and a constant load from the speed and
//! angle of drive logs, driven by the torque of the electrical model fitted to the same logs
//! (or of a given `K_t`), with the friction per log for a trend: what `greybox mechanics`
//! and Python's `mechanics` ask ([`MechanicsRequest`]) and their joint report
//! ([`mechanics`]).

use super::report::{Report, read_with_channel};
use super::shaft;
use crate::Experiment;
use crate::app::LogReading;
use crate::error::{Error, Result};
use crate::estimate::FitResult;
use crate::pmsm::{
    Axis, DqSource, LOAD_TORQUE, LogSource, MechanicsFit, MechanicsOptions, MechanicsTerms, MotorParameters,
    PmsmFitOptions, SQRT_2_3, fit_mechanics, fit_pmsm,
};
use serde::Serialize;

/// A mechanical fit as asked for. Units SI; on a linear axis (`lead`, `pole_pitch`) the
/// report is in kg, N s/m and N.
#[derive(Clone, Debug, PartialEq)]
pub struct MechanicsRequest {
    /// Pole pairs n_p.
    pub pole_pairs: u32,
    /// A known torque constant K_t \[N m/A, peak dq current\] instead of the electrical
    /// fit: then only the time, `iq`, the speed (and the angle with `gravity`) are read.
    pub k_t: Option<f64>,
    /// A linear axis driven through a screw, rack or belt: metres of travel per motor
    /// revolution \[m\].
    pub lead: Option<f64>,
    /// A linear motor of this pole pitch \[m\], whose speed and position columns are in m/s
    /// and m (read as a shaft of lead `2 n_p τ_p`).
    pub pole_pitch: Option<f64>,
    /// A known force constant K_f \[N/A\] of a linear axis instead of the electrical fit.
    pub k_f: Option<f64>,
    /// A gravity load `m g l sin θ_m` (angle 0 hanging down).
    pub gravity: bool,
    /// A constant load torque `t_0`.
    pub constant_load: bool,
    /// Viscous and Coulomb friction per log (inertia and loads shared).
    pub per_log: bool,
    /// Window length \[s\] (default 0.01).
    pub window: f64,
    /// Speed \[rad/s; m/s on a linear axis\] over which the Coulomb friction changes sign;
    /// `None`: estimated (the lowest loss between 1e-4 and 1 times the logs' peak speed).
    pub coulomb_speed: Option<f64>,
    /// Column of a load torque \[N m\] (a force \[N\] on a linear axis), used when every
    /// log has it.
    pub col_load: String,
    /// How the logs are read (as a fit reads them).
    pub reading: LogReading,
}

impl MechanicsRequest {
    /// The command line's defaults for a motor of `pole_pairs`.
    pub fn new(pole_pairs: u32) -> Self {
        Self {
            pole_pairs,
            k_t: None,
            lead: None,
            pole_pitch: None,
            k_f: None,
            gravity: false,
            constant_load: false,
            per_log: false,
            window: 0.01,
            coulomb_speed: None,
            col_load: LOAD_TORQUE.into(),
            reading: LogReading::default(),
        }
    }
}

/// The joint electrical and mechanical report.
#[derive(Serialize)]
struct Joint<'a> {
    /// The electrical fit that gave the torque model (none with a given `K_t`).
    electrical: Option<&'a FitResult>,
    /// The torque model.
    motor: MotorParameters,
    /// The mechanical fit.
    mechanics: &'a MechanicsFit,
}

/// The fits of `logs` (files or tables, fitted jointly) as `r` asks: the electrical model first unless
/// `K_t` or `K_f` is given, then the mechanics ([`fit_mechanics`]); their joint report,
/// untrusted when either fit is (codes `electrical …`, `mechanics …`).
///
/// # Errors
/// [`Error::InvalidOption`] naming the flag for options that exclude each other (`--k-t`
/// and `--k-f`, `--lead` and `--pole-pitch`), `--k-f` without a linear axis, a `K_t` that is
/// not finite and non-zero, a length that is not positive; bad paths, unreadable logs, a
/// failed fit.
pub fn mechanics(logs: &[LogSource<'_>], r: &MechanicsRequest) -> Result<Report> {
    exclusive(r)?;
    let axis = axis(r)?;
    let terms = MechanicsTerms { gravity: r.gravity, constant: r.constant_load };
    // The axis' faults before the electrical fit spends its time.
    axis.check(terms)?;
    let k_t = r.k_t.or(r.k_f.map(|k_f| k_f / axis.radians_per_unit()));
    let logs: Vec<Experiment> = match k_t {
        Some(_) => shaft::read_mechanical(logs, &r.reading, r.pole_pairs, r.gravity, &r.col_load)?,
        None => read_with_channel(logs, &r.reading, r.pole_pairs, (r.col_load.as_str(), LOAD_TORQUE, "N m"))?,
    };
    let logs = match r.pole_pitch {
        Some(_) => logs.into_iter().map(|e| shaft::linear_motor(e, axis)).collect::<Result<_>>()?,
        None => logs,
    };
    // The angle a gravity term needs, before the electrical fit spends its time.
    for e in logs.iter().filter(|_| r.gravity) {
        e.channel("theta_m")?;
    }
    let n_p = r.pole_pairs;
    let (electrical, motor) = match k_t {
        Some(k_t) if k_t.is_finite() && k_t != 0.0 => {
            (None, MotorParameters { r_s: 0.0, l_d: 0.0, l_q: 0.0, psi_f: k_t / (1.5 * f64::from(n_p)), n_p })
        }
        Some(k_t) => {
            let (flag, what) = if r.k_f.is_some() { ("--k-f", "K_f") } else { ("--k-t", "K_t") };
            let given = r.k_f.unwrap_or(k_t);
            return Err(Error::InvalidOption {
                option: flag.into(),
                reason: format!("{given}: {what} must be finite and non-zero"),
            });
        }
        None => {
            let fit = fit_pmsm(&logs, &PmsmFitOptions::new(n_p))?.report;
            let motor = motor_of(&fit, n_p);
            (Some(fit), motor)
        }
    };
    // K_t's relative standard error from the electrical fit (0 for a given K_t).
    let k_t_relative_se = electrical
        .as_ref()
        .and_then(|e| e.derived("k_t"))
        .map_or(0.0, |k| if k.std_error.is_finite() { (k.std_error / k.value).abs() } else { 0.0 });
    let options = MechanicsOptions {
        k_t_relative_se,
        window: r.window,
        coulomb_speed: r.coulomb_speed,
        terms,
        per_log_friction: r.per_log,
        axis,
        ..MechanicsOptions::new(motor)
    };
    let mechanics = fit_mechanics(&logs, &options)?;
    let mut text = String::new();
    if let Some(e) = &electrical {
        text += &format!("Electrical fit (the torque model):\n{}\n", crate::pmsm::estimate_table(e));
    }
    text += &mechanics.to_string();
    let mut untrusted: Vec<String> = electrical
        .as_ref()
        .map(|e| e.untrusted_codes().into_iter().map(|c| format!("electrical {c}")).collect())
        .unwrap_or_default();
    untrusted.extend(mechanics.fit.untrusted_codes().into_iter().map(|c| format!("mechanics {c}")));
    let joint = Joint { electrical: electrical.as_ref(), motor, mechanics: &mechanics };
    Ok(Report::new(text, &joint, untrusted))
}

/// The options that exclude or need each other (the command line's parser checks them
/// too): `--k-t` and `--k-f`, `--lead` and `--pole-pitch`, `--k-f` only on a linear axis.
///
/// # Errors
/// [`Error::InvalidOption`] naming the second flag.
fn exclusive(r: &MechanicsRequest) -> Result<()> {
    let bad =
        |flag: &str, reason: &str| Err(Error::InvalidOption { option: flag.into(), reason: reason.into() });
    if r.k_t.is_some() && r.k_f.is_some() {
        return bad(
            "--k-f",
            "not with --k-t: give the torque constant of a shaft or the force constant of a linear axis",
        );
    }
    if r.lead.is_some() && r.pole_pitch.is_some() {
        return bad(
            "--pole-pitch",
            "not with --lead: a screw or rack (--lead) or a linear motor (--pole-pitch)",
        );
    }
    if r.k_f.is_some() && r.lead.is_none() && r.pole_pitch.is_none() {
        return bad("--k-f", "a force constant needs a linear axis: give --lead or --pole-pitch");
    }
    Ok(())
}

/// The axis of `lead` or `pole_pitch` (a linear motor: lead `2 n_p τ_p`), or the shaft.
///
/// # Errors
/// [`Error::InvalidOption`] naming the flag for a length that is not positive and finite,
/// and `--pole-pitch` with phase currents or a speed or angle unit or frame (its columns are
/// in m/s and m).
fn axis(r: &MechanicsRequest) -> Result<Axis> {
    let positive = |flag: &str, x: f64| {
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(Error::InvalidOption {
                option: flag.into(),
                reason: format!("{x} m: a length must be positive and finite"),
            })
        }
    };
    if let Some(tau_p) = r.pole_pitch {
        let csv = &r.reading.csv;
        if csv.source == DqSource::Phases {
            return Err(Error::InvalidOption {
                option: "--pole-pitch".into(),
                reason:
                    "not with --dq-from-phases: the Park transform would take the position in metres for an \
                         angle; give the dq columns"
                        .into(),
            });
        }
        if csv.speed_factor(r.pole_pairs) != 1.0 || csv.angle_factor(r.pole_pairs) != 1.0 {
            return Err(Error::InvalidOption {
                option: "--pole-pitch".into(),
                reason:
                    "a linear motor's speed and position columns are read in m/s and m: drop --speed-unit, \
                         --angle-unit, --speed-frame and --negate-speed"
                        .into(),
            });
        }
        return Ok(Axis::Linear { lead: 2.0 * f64::from(r.pole_pairs) * positive("--pole-pitch", tau_p)? });
    }
    Ok(r.lead.map(|l| positive("--lead", l)).transpose()?.map_or(Axis::Rotary, |lead| Axis::Linear { lead }))
}

/// The torque model of an electrical fit: `ψ_f = K_e √(2/3) / n_p` (MODEL.md §1), the
/// inductances `l_d, l_q` (or `l_s` for both).
fn motor_of(fit: &FitResult, n_p: u32) -> MotorParameters {
    let value = |name: &str| fit.parameter(name).map(|p| p.value);
    let l_s = value("l_s").unwrap_or(0.0);
    MotorParameters {
        r_s: value("r_s").unwrap_or(0.0),
        l_d: value("l_d").unwrap_or(l_s),
        l_q: value("l_q").unwrap_or(l_s),
        psi_f: value("k_e").unwrap_or(f64::NAN) * SQRT_2_3 / f64::from(n_p),
        n_p,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_that_exclude_each_other_are_named() {
        let option = |r: MechanicsRequest| match mechanics(&[], &r) {
            Err(Error::InvalidOption { option, .. }) => option,
            other => panic!("{other:?}"),
        };
        let both =
            MechanicsRequest { k_t: Some(0.6), k_f: Some(2.0), lead: Some(0.01), ..MechanicsRequest::new(4) };
        assert_eq!(option(both), "--k-f");
        let shaft = MechanicsRequest { k_f: Some(2.0), ..MechanicsRequest::new(4) };
        assert_eq!(option(shaft), "--k-f");
        let axes = MechanicsRequest { lead: Some(0.01), pole_pitch: Some(0.02), ..MechanicsRequest::new(4) };
        assert_eq!(option(axes), "--pole-pitch");
        let lead = MechanicsRequest { lead: Some(-1.0), ..MechanicsRequest::new(4) };
        assert_eq!(option(lead), "--lead");
    }
}
