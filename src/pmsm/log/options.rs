//! The options of the PMSM log reader: column names, units, frames and scaling, the
//! source of the dq signals, read limits and the sample-time plausibility range.

use crate::data::TimeWindow;
use crate::data::{Delimiter, ReadLimits};
use serde::{Deserialize, Serialize};

/// Header names of the columns a log may hold, one per signal; every name is remappable.
///
/// The defaults are the header names of the development logs in `../shared/data`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct ColumnNames {
    /// Time `t_k` \[s\] (required). Default `t`.
    pub t: String,
    /// d-axis voltage, period mean over `[t_k, t_k + h)` (required for [`DqSource::Dq`]).
    /// Default `ud`.
    pub u_d: String,
    /// q-axis voltage, period mean (required for [`DqSource::Dq`]). Default `uq`.
    pub u_q: String,
    /// d-axis current at `t_k` (required for [`DqSource::Dq`]). Default `id`.
    pub i_d: String,
    /// q-axis current at `t_k` (required for [`DqSource::Dq`]). Default `iq`.
    pub i_q: String,
    /// Rotor speed at `t_k` (required). Default `w_m`.
    pub w_m: String,
    /// Rotor angle at `t_k` (optional; required for [`DqSource::Phases`]). Default `theta_m`.
    pub theta_m: String,
    /// d-axis voltage reference computed at `t_k` (optional). Default `ud_ref`.
    pub u_d_ref: String,
    /// q-axis voltage reference computed at `t_k` (optional). Default `uq_ref`.
    pub u_q_ref: String,
    /// Phase-a current at `t_k` (required for [`DqSource::Phases`]). Default `ia`.
    pub i_a: String,
    /// Phase-b current at `t_k` (required for [`DqSource::Phases`]). Default `ib`.
    pub i_b: String,
    /// Phase-c current at `t_k` (required for [`DqSource::Phases`]). Default `ic`.
    pub i_c: String,
    /// Phase-a to neutral voltage, period mean (required for [`DqSource::Phases`]).
    /// Default `ua`.
    pub u_a: String,
    /// Phase-b to neutral voltage, period mean (required for [`DqSource::Phases`]).
    /// Default `ub`.
    pub u_b: String,
    /// Phase-c to neutral voltage, period mean (required for [`DqSource::Phases`]).
    /// Default `uc`.
    pub u_c: String,
    /// Further columns carried through unscaled as channels under their header names, when
    /// present (absent ones are skipped): e.g. a winding temperature `t_winding` \[°C\] for
    /// the standstill fit. Default none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra: Vec<String>,
}

impl Default for ColumnNames {
    fn default() -> Self {
        let s = |x: &str| x.to_string();
        Self {
            t: s("t"),
            u_d: s("ud"),
            u_q: s("uq"),
            i_d: s("id"),
            i_q: s("iq"),
            w_m: s("w_m"),
            theta_m: s("theta_m"),
            u_d_ref: s("ud_ref"),
            u_q_ref: s("uq_ref"),
            i_a: s("ia"),
            i_b: s("ib"),
            i_c: s("ic"),
            u_a: s("ua"),
            u_b: s("ub"),
            u_c: s("uc"),
            extra: Vec::new(),
        }
    }
}

impl ColumnNames {
    /// The standard names of the columns, each the default header name of one field: `t`,
    /// `ud`, `uq`, `id`, `iq`, `w_m`, `theta_m`, `ud_ref`, `uq_ref`, `ia`, `ib`, `ic`, `ua`,
    /// `ub`, `uc` (the keys of [`ColumnNames::column_mut`] and of the command line's
    /// `--columns id=Id,…`).
    pub const STANDARD: [&'static str; 15] = [
        "t", "ud", "uq", "id", "iq", "w_m", "theta_m", "ud_ref", "uq_ref", "ia", "ib", "ic", "ua", "ub", "uc",
    ];

    /// The header name read for the column whose standard name is `standard`
    /// ([`ColumnNames::STANDARD`]), to set it: `names.column_mut("id")` is `names.i_d`.
    /// `None` for a name that is not standard.
    pub fn column_mut(&mut self, standard: &str) -> Option<&mut String> {
        Some(match standard {
            "t" => &mut self.t,
            "ud" => &mut self.u_d,
            "uq" => &mut self.u_q,
            "id" => &mut self.i_d,
            "iq" => &mut self.i_q,
            "w_m" => &mut self.w_m,
            "theta_m" => &mut self.theta_m,
            "ud_ref" => &mut self.u_d_ref,
            "uq_ref" => &mut self.u_q_ref,
            "ia" => &mut self.i_a,
            "ib" => &mut self.i_b,
            "ic" => &mut self.i_c,
            "ua" => &mut self.u_a,
            "ub" => &mut self.u_b,
            "uc" => &mut self.u_c,
            _ => return None,
        })
    }
}

/// Unit of the speed column.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpeedUnit {
    /// Radians per second (default).
    #[default]
    #[cfg_attr(feature = "cli", value(name = "rad/s", alias = "rad-s"))]
    RadPerSec,
    /// Revolutions per minute; multiplied by `2π/60` on reading.
    Rpm,
}

/// Unit of the time column; the reader converts it to seconds.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeUnit {
    /// Seconds (default).
    #[default]
    S,
    /// Milliseconds; divided by 10³ on reading.
    Ms,
    /// Microseconds; divided by 10⁶ on reading.
    Us,
}

impl TimeUnit {
    /// Units of this kind in one second: 1, 10³ or 10⁶. The reader divides by it (a
    /// division, so that a time exactly representable in seconds converts exactly).
    pub fn per_second(self) -> f64 {
        match self {
            Self::S => 1.0,
            Self::Ms => 1e3,
            Self::Us => 1e6,
        }
    }

    /// The unit's name on the command line: `s`, `ms`, `us`.
    pub fn name(self) -> &'static str {
        match self {
            Self::S => "s",
            Self::Ms => "ms",
            Self::Us => "us",
        }
    }
}

/// Whether the speed and angle columns are mechanical or electrical quantities.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Frame {
    /// Mechanical speed and angle (default): `w_m`, `θ_m`.
    #[default]
    Mechanical,
    /// Electrical speed and angle `w_e = n_p w_m`, `θ_e = n_p θ_m`: divided by `n_p` on
    /// reading. A wrapped `θ_e` gives a `θ_m` in `[−π/n_p, π/n_p)`, which is all that
    /// matters for `θ_e = n_p θ_m`.
    Electrical,
}

/// Unit of the angle column.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AngleUnit {
    /// Radians (default).
    #[default]
    Rad,
    /// Degrees; multiplied by `π/180` on reading.
    Deg,
}

/// Scaling of current or voltage columns (MODEL.md §1).
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scale {
    /// Amplitude-invariant peak values (default), what the library uses: a phase peak `X̂`
    /// gives `|x_dq| = X̂`.
    #[default]
    Peak,
    /// RMS-scaled values (`|x_dq|` = phase RMS, as some drives log): multiplied by `√2` on
    /// reading. Power-invariant dq scaling (`|x_dq| = √(3/2)` × phase peak) is not this.
    Rms,
}

impl Scale {
    /// Factor from a column in this scaling to amplitude-invariant peak values: 1 or `√2`.
    pub fn factor(self) -> f64 {
        match self {
            Self::Peak => 1.0,
            Self::Rms => std::f64::consts::SQRT_2,
        }
    }
}

/// Where the dq currents and voltages come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DqSource {
    /// The dq columns `u_d, u_q, i_d, i_q` (default).
    #[default]
    Dq,
    /// Computed from the phase columns and `theta_m`: currents by Clarke and Park at
    /// `θ_e = n_p θ_m`, voltages as period means of a voltage held in the **stator** frame
    /// ([`crate::pmsm::log::transform::stator_held_voltages_to_dq`],
    /// MODEL.md §4). Phase voltages computed from a dq-held voltage (gym-electric-motor)
    /// do not fit this model; read those logs with [`DqSource::Dq`].
    Phases,
}

/// How to read a log: column names, units and the source of the dq signals.
///
/// `Default` reads the development logs in `../shared/data` as they are: SI units,
/// mechanical speed and angle, peak scaling, dq columns.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct CsvOptions {
    /// Pole pairs n_p, needed only to convert an electrical speed or angle
    /// ([`Frame::Electrical`]) or phase quantities ([`DqSource::Phases`]); `None` otherwise.
    pub pole_pairs: Option<u32>,
    /// Header names of the columns.
    pub columns: ColumnNames,
    /// Unit of the speed column (default rad/s).
    pub speed_unit: SpeedUnit,
    /// Whether speed and angle are mechanical (default) or electrical.
    pub speed_frame: Frame,
    /// Negate the speed column on reading: a drive that counts its speed the other way
    /// than its dq frame turns (the angle column is read as it is). Default `false`.
    pub negate_speed: bool,
    /// Unit of the angle column (default rad).
    pub angle_unit: AngleUnit,
    /// Scaling of the current columns, dq or phase (default peak).
    pub current_scale: Scale,
    /// Scaling of the voltage columns, dq, references or phase (default peak).
    pub voltage_scale: Scale,
    /// Source of the dq signals (default: the dq columns).
    pub source: DqSource,
    /// Bounds on line length, field count and rows ([`ReadLimits`]; defaults a real log
    /// never reaches).
    pub limits: ReadLimits,
    /// Unit of the time column (default s), converted to seconds before anything else:
    /// the window, the gaps and the sample-time plausibility all see seconds.
    pub time_unit: TimeUnit,
    /// Samples kept, by their time \[s\] after the unit conversion: `from ≤ t ≤ to`, both
    /// inclusive (default: all). With a window, the time column is checked on the kept rows
    /// only, so a gap outside it is no error.
    pub window: TimeWindow,
    /// Skip the plausibility limit on the sample time ([`MIN_SAMPLE_TIME`] ≤ h ≤
    /// [`MAX_SAMPLE_TIME`]). Default `false`.
    pub force: bool,
    /// The log may be for the steady-state equations (`greybox fit`, which chooses them for
    /// a slow log or is asked for them): the longest plausible sample time is then
    /// [`MAX_STEADY_SAMPLE_TIME`] (slow telemetry), not [`MAX_SAMPLE_TIME`]. Default `false`.
    pub steady_state: bool,
    /// The field delimiter of a CSV log ([`Delimiter`]: `,` by default, `;`, tab or `|`);
    /// Parquet and Arrow logs ignore it.
    pub delimiter: Delimiter,
}

impl CsvOptions {
    /// Factor from the speed column to the mechanical speed \[rad/s\] of a motor with `n_p`
    /// pole pairs: the sign of [`CsvOptions::negate_speed`], `1/n_p` for an electrical speed,
    /// `π/30` for rpm.
    pub fn speed_factor(&self, n_p: u32) -> f64 {
        let sign = if self.negate_speed { -1.0 } else { 1.0 };
        sign * self.frame_factor(n_p)
            * match self.speed_unit {
                SpeedUnit::RadPerSec => 1.0,
                SpeedUnit::Rpm => std::f64::consts::PI / 30.0,
            }
    }

    /// Factor from the angle column to the mechanical angle \[rad\] of a motor with `n_p`
    /// pole pairs: `1/n_p` for an electrical angle, `π/180` for degrees.
    pub fn angle_factor(&self, n_p: u32) -> f64 {
        self.frame_factor(n_p)
            * match self.angle_unit {
                AngleUnit::Rad => 1.0,
                AngleUnit::Deg => std::f64::consts::PI / 180.0,
            }
    }

    /// `1/n_p` for electrical speed and angle columns, else 1.
    fn frame_factor(&self, n_p: u32) -> f64 {
        match self.speed_frame {
            Frame::Mechanical => 1.0,
            Frame::Electrical => 1.0 / f64::from(n_p),
        }
    }
}

/// Shortest plausible sample time of a drive log: 100 ns (10 MHz, beyond any drive's
/// control rate). A shorter h is most likely a time column in other units than seconds.
pub const MIN_SAMPLE_TIME: f64 = 1e-7;

/// Longest plausible sample time of a drive log: 100 ms (10 Hz, far too slow for the
/// electrical dynamics the models describe). A longer h is most likely a time column in
/// ms read as s.
pub const MAX_SAMPLE_TIME: f64 = 0.1;

/// Longest plausible sample time of a log for the steady-state equations: 10 s (0.1 Hz,
/// the slowest fleet telemetry; the Paderborn motor-temperature set logs at 2 Hz).
pub const MAX_STEADY_SAMPLE_TIME: f64 = 10.0;
