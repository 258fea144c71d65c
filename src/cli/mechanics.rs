//! `greybox mechanics`: inertia, viscous and Coulomb friction, gravity and a constant load
//! from the speed and angle of drive logs, driven by the torque of the electrical model
//! fitted to the same logs (or of a given `K_t`), with the friction per log for a trend
//! (issue 33).

use super::columns::ColumnArgs;
use super::output;
use crate::app::{MechanicsRequest, mechanics};
use crate::pmsm::LOAD_TORQUE;
use crate::pmsm::LogSource;
use clap::Args;
use std::path::PathBuf;

/// Arguments of `greybox mechanics`.
#[derive(Args, Debug)]
#[command(
    after_help = "The logs are read as by `greybox fit`; without --k-t the electrical model is fitted to them \
first (jointly) and its torque 1.5 n_p (ψ_f i_q + (L_d − L_q) i_d i_q) drives the shaft. A load-torque column \
(--col-load) is subtracted when every log has it. The intervals take the torque model as exact. A linear axis \
(--lead for a screw or rack, --pole-pitch for a linear motor) is reported in kg, N s/m and N. See \
docs/mechanics.md."
)]
#[command(group = clap::ArgGroup::new("linear").args(["lead", "pole_pitch"]).multiple(false))]
pub struct MechanicsArgs {
    /// Drive logs (CSV, plain or gzip; Parquet, Arrow IPC), fitted jointly.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Number of pole pairs n_p of the motor.
    #[arg(long, short = 'p')]
    pub pole_pairs: u32,
    /// A known torque constant K_t [N m/A, peak dq current] instead of the electrical fit:
    /// then only the time, iq, the speed (and the angle with --gravity) are read.
    #[arg(long, value_name = "N m/A", conflicts_with = "k_f")]
    pub k_t: Option<f64>,
    /// A linear axis driven through a screw, rack or belt: M metres of travel per motor
    /// revolution (a ball screw's lead over the gear ratio); the logs are the motor's, the
    /// report in kg, N s/m and N.
    #[arg(long, value_name = "M", conflicts_with = "pole_pitch")]
    pub lead: Option<f64>,
    /// A linear motor of pole pitch M [m] whose speed and position columns are in m/s and m
    /// (read as a shaft of lead 2 n_p M); the report in kg, N s/m and N.
    #[arg(long, value_name = "M")]
    pub pole_pitch: Option<f64>,
    /// A known force constant K_f [N/A, peak dq current] of a linear axis (--lead or
    /// --pole-pitch) instead of the electrical fit, read as --k-t is.
    #[arg(long, value_name = "N/A", requires = "linear")]
    pub k_f: Option<f64>,
    /// A gravity load m g l sin θ_m (angle 0 hanging down).
    #[arg(long)]
    pub gravity: bool,
    /// A constant load torque t_0.
    #[arg(long)]
    pub constant_load: bool,
    /// Viscous and Coulomb friction per log (inertia and loads shared): the friction trend.
    #[arg(long)]
    pub per_log: bool,
    /// Window length [s].
    #[arg(long, default_value_t = 0.01, value_name = "S")]
    pub window: f64,
    /// Speed [rad/s; m/s on a linear axis] over which the Coulomb friction changes sign, or
    /// `estimate` (the lowest loss between 1e-4 and 1 times the logs' peak speed).
    #[arg(long, default_value = "estimate", value_name = "SPEED|estimate", value_parser = |s: &str| super::args::Pll::positive_or_estimate(s, "a positive speed in rad/s"))]
    pub coulomb_speed: super::args::Pll,
    /// Column of a load torque [N m] (on a linear axis a force [N]), used when every log has it.
    #[arg(long, default_value = LOAD_TORQUE, value_name = "NAME")]
    pub col_load: String,
    /// The report's outputs.
    #[command(flatten)]
    pub report: output::ReportArgs,
    /// Log columns and units (as `greybox fit`).
    #[command(flatten)]
    pub columns: ColumnArgs,
}

impl From<&MechanicsArgs> for MechanicsRequest {
    /// The request of these flags.
    fn from(a: &MechanicsArgs) -> Self {
        Self {
            pole_pairs: a.pole_pairs,
            k_t: a.k_t,
            lead: a.lead,
            pole_pitch: a.pole_pitch,
            k_f: a.k_f,
            gravity: a.gravity,
            constant_load: a.constant_load,
            per_log: a.per_log,
            window: a.window,
            coulomb_speed: match a.coulomb_speed {
                super::args::Pll::Bandwidth(w_c) => Some(w_c),
                _ => None,
            },
            col_load: a.col_load.clone(),
            reading: a.columns.reading(),
        }
    }
}

/// Runs `greybox mechanics`; whether both fits are trusted.
///
/// # Errors
/// Unreadable logs, a bad `--k-t`, window or ω_c, a failed fit, an output that cannot be
/// written (nothing is written then).
pub fn run_mechanics(a: &MechanicsArgs) -> crate::Result<bool> {
    a.report.run(&a.logs, "fit", || mechanics(&LogSource::files(&a.logs), &MechanicsRequest::from(a)))
}
