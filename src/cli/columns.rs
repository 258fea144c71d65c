//! The CSV-reading flags shared by `fit`, `validate` and `track`: column names, units,
//! frames and scaling, read limits, the time window and the split at gaps; mapped to the
//! library's [`CsvOptions`].

use crate::Experiment;
use crate::app::LogReading;
use crate::data::Delimiter;
use crate::data::TimeWindow;
use crate::pmsm::{AngleUnit, ColumnNames, CsvOptions, DqSource, Frame, Scale, SpeedUnit, TimeUnit};
use clap::Args;
use std::path::PathBuf;

/// The log-reading flags shared by `fit`, `validate` and `track` (see the module doc).
#[derive(Args, Debug)]
pub struct ColumnArgs {
    /// Time column [s].
    #[arg(help_heading = "Log columns", long, default_value = "t")]
    pub col_t: String,
    /// d-axis voltage column.
    #[arg(help_heading = "Log columns", long, default_value = "ud")]
    pub col_ud: String,
    /// q-axis voltage column.
    #[arg(help_heading = "Log columns", long, default_value = "uq")]
    pub col_uq: String,
    /// d-axis current column.
    #[arg(help_heading = "Log columns", long, default_value = "id")]
    pub col_id: String,
    /// q-axis current column.
    #[arg(help_heading = "Log columns", long, default_value = "iq")]
    pub col_iq: String,
    /// Speed column.
    #[arg(help_heading = "Log columns", long, default_value = "w_m")]
    pub col_w: String,
    /// Rotor angle column (optional; needed with --dq-from-phases).
    #[arg(help_heading = "Log columns", long, default_value = "theta_m")]
    pub col_theta: String,
    /// d-axis voltage reference column (optional).
    #[arg(help_heading = "Log columns", long, default_value = "ud_ref")]
    pub col_ud_ref: String,
    /// q-axis voltage reference column (optional).
    #[arg(help_heading = "Log columns", long, default_value = "uq_ref")]
    pub col_uq_ref: String,
    /// Phase current columns, three names comma separated (with --dq-from-phases).
    #[arg(help_heading = "Log columns", long, value_name = "A,B,C", default_value = "ia,ib,ic", value_parser = parse_phases)]
    pub col_i_abc: Phases,
    /// Phase voltage columns, three names comma separated (with --dq-from-phases).
    #[arg(help_heading = "Log columns", long, value_name = "A,B,C", default_value = "ua,ub,uc", value_parser = parse_phases)]
    pub col_u_abc: Phases,
    /// All renamed columns in one flag: STANDARD=HEADER pairs, comma separated, e.g.
    /// `--columns id=Id,iq=Iq,ud=Ud,uq=Uq,w_m=speed_rpm`; the standard names are the
    /// per-column flags' defaults (t, ud, uq, id, iq, w_m, theta_m, ud_ref, uq_ref, ia, ib,
    /// ic, ua, ub, uc). Not together with those flags.
    #[arg(
        help_heading = "Log columns",
        long,
        value_name = "STD=NAME,...",
        value_parser = parse_columns,
        conflicts_with_all = ["col_t", "col_ud", "col_uq", "col_id", "col_iq", "col_w", "col_theta", "col_ud_ref", "col_uq_ref", "col_i_abc", "col_u_abc"]
    )]
    pub columns: Option<ColumnMap>,
    /// Unit of the speed column.
    #[arg(help_heading = "Units and frames", long, value_parser = super::values::listed::<SpeedUnit>(), default_value = "rad/s")]
    pub speed_unit: SpeedUnit,
    /// Unit of the angle column.
    #[arg(help_heading = "Units and frames", long, value_parser = super::values::listed::<AngleUnit>(), default_value = "rad")]
    pub angle_unit: AngleUnit,
    /// Whether the speed and angle columns are mechanical or electrical.
    #[arg(help_heading = "Units and frames", long, value_parser = super::values::listed::<Frame>(), default_value = "mechanical")]
    pub speed_frame: Frame,
    /// Negate the speed column on reading (a drive whose speed counts the other way than
    /// its dq frame turns; the angle column is read as it is).
    #[arg(help_heading = "Units and frames", long)]
    pub negate_speed: bool,
    /// Scaling of the current columns (peak: |i_dq| = phase peak; rms: |i_dq| = phase RMS).
    #[arg(help_heading = "Units and frames", long, value_parser = super::values::listed::<Scale>(), default_value = "peak")]
    pub current_scale: Scale,
    /// Scaling of the voltage columns.
    #[arg(help_heading = "Units and frames", long, value_parser = super::values::listed::<Scale>(), default_value = "peak")]
    pub voltage_scale: Scale,
    /// Compute dq currents and voltages from the phase columns and the rotor angle.
    #[arg(help_heading = "Units and frames", long)]
    pub dq_from_phases: bool,
    /// Unit of the time column (--col-t), converted to seconds before the window, the gap
    /// check and the sample-time plausibility limits.
    #[arg(help_heading = "Units and frames", long, value_parser = super::values::listed::<TimeUnit>(), default_value = "s")]
    pub time_unit: TimeUnit,
    /// Keep only the samples with t >= SECONDS (inclusive; time after --time-unit). Must be
    /// before --to; the window must hold at least 8 samples.
    #[arg(
        help_heading = "Time window and checks",
        long,
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub from: Option<f64>,
    /// Keep only the samples with t <= SECONDS (inclusive; time after --time-unit).
    #[arg(
        help_heading = "Time window and checks",
        long,
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub to: Option<f64>,
    /// Split each log at the gaps of its time column (a step back, or one longer than 1.5
    /// times the median step) into segments fitted jointly, each with its own initial state,
    /// named LOG#1, LOG#2, ...; segments under 8 samples (`MIN_SAMPLES`) are dropped with a warning.
    #[arg(help_heading = "Time window and checks", long)]
    pub split_gaps: bool,
    /// Skip the plausibility limits (sample time h in [100 ns, 100 ms]; speeds, currents and
    /// voltages within ±1e6 rad/s, ±1e6 A, ±1e7 V) and fit a log whose
    /// sample time the model cannot resolve (h beyond 5 L/R, or half an electrical turn per
    /// sample), otherwise refused before the fit.
    #[arg(help_heading = "Time window and checks", long)]
    pub force: bool,
    /// Longest line of a log in bytes; a longer one stops the read (default 1 MiB).
    #[arg(help_heading = "Reading limits", long, default_value_t = crate::data::ReadLimits::default().max_line_bytes)]
    pub max_line_bytes: u64,
    /// Most columns in a log's header (default 4096).
    #[arg(help_heading = "Reading limits", long, default_value_t = crate::data::ReadLimits::default().max_fields)]
    pub max_fields: usize,
    /// Most data rows in a log (default 10^8).
    #[arg(help_heading = "Reading limits", long, default_value_t = crate::data::ReadLimits::default().max_rows)]
    pub max_rows: u64,
    /// Field delimiter of CSV logs: `,` `;` `tab` (or `\t`) `|`; Parquet/Arrow ignore it.
    #[arg(help_heading = "Reading limits", long, default_value = ",", value_parser = |s: &str| s.parse::<Delimiter>().map_err(|e| e.to_string()))]
    pub delimiter: Delimiter,
}

/// Three phase column names `a, b, c`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Phases(pub [String; 3]);

/// Parses `A,B,C` (three non-empty names, spaces around them dropped). One word with
/// commas, so that the flag never takes a following log path as a second value.
fn parse_phases(s: &str) -> Result<Phases, String> {
    let names: Vec<String> = s.split(',').map(|n| n.trim().to_string()).collect();
    match <[String; 3]>::try_from(names) {
        Ok(n) if n.iter().all(|x| !x.is_empty()) => Ok(Phases(n)),
        _ => Err(format!("`{s}`: expected three column names separated by commas, e.g. ia,ib,ic")),
    }
}

/// The pairs of `--columns`: (standard name, header name), each standard name once.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ColumnMap(pub Vec<(String, String)>);

/// Parses `STD=NAME,...` ([`ColumnNames::STANDARD`] names on the left, non-empty header
/// names on the right, each standard name once).
fn parse_columns(s: &str) -> Result<ColumnMap, String> {
    let mut pairs: Vec<(String, String)> = Vec::new();
    for item in s.split(',') {
        let Some((key, name)) = item.split_once('=') else {
            return Err(format!("`{item}`: expected STANDARD=HEADER, e.g. id=Id"));
        };
        let (key, name) = (key.trim(), name.trim());
        if !ColumnNames::STANDARD.contains(&key) {
            return Err(format!(
                "`{key}` is not a standard column name; one of {}",
                ColumnNames::STANDARD.join(", ")
            ));
        }
        if name.is_empty() {
            return Err(format!("`{item}`: the header name after `=` is empty"));
        }
        if pairs.iter().any(|(k, _)| k == key) {
            return Err(format!("`{key}` is given twice"));
        }
        pairs.push((key.to_string(), name.to_string()));
    }
    Ok(ColumnMap(pairs))
}

impl ColumnArgs {
    /// The reader's options of these flags (pole pairs `None`: the command sets them).
    pub fn options(&self) -> CsvOptions {
        CsvOptions {
            pole_pairs: None,
            columns: self.column_names(),
            speed_unit: self.speed_unit,
            speed_frame: self.speed_frame,
            negate_speed: self.negate_speed,
            angle_unit: self.angle_unit,
            current_scale: self.current_scale,
            voltage_scale: self.voltage_scale,
            source: if self.dq_from_phases { DqSource::Phases } else { DqSource::Dq },
            limits: crate::data::ReadLimits {
                max_line_bytes: self.max_line_bytes,
                max_fields: self.max_fields,
                max_rows: self.max_rows,
            },
            time_unit: self.time_unit,
            window: TimeWindow { from: self.from, to: self.to },
            force: self.force,
            steady_state: false,
            delimiter: self.delimiter,
        }
    }

    /// The header names of the per-column flags, or of `--columns`.
    fn column_names(&self) -> ColumnNames {
        let mut names = ColumnNames {
            t: self.col_t.clone(),
            u_d: self.col_ud.clone(),
            u_q: self.col_uq.clone(),
            i_d: self.col_id.clone(),
            i_q: self.col_iq.clone(),
            w_m: self.col_w.clone(),
            theta_m: self.col_theta.clone(),
            u_d_ref: self.col_ud_ref.clone(),
            u_q_ref: self.col_uq_ref.clone(),
            i_a: self.col_i_abc.0[0].clone(),
            i_b: self.col_i_abc.0[1].clone(),
            i_c: self.col_i_abc.0[2].clone(),
            u_a: self.col_u_abc.0[0].clone(),
            u_b: self.col_u_abc.0[1].clone(),
            u_c: self.col_u_abc.0[2].clone(),
            extra: Vec::new(),
        };
        for (key, name) in self.columns.iter().flat_map(|m| &m.0) {
            // Every key was checked when the flag was parsed.
            if let Some(column) = names.column_mut(key) {
                column.clone_from(name);
            }
        }
        names
    }

    /// The reading these flags ask for: the reader's options and `--split-gaps`.
    pub fn reading(&self) -> LogReading {
        LogReading { csv: self.options(), split_gaps: self.split_gaps }
    }

    /// Reads `paths` with `csv` (from [`ColumnArgs::options`]) as [`crate::app::read_logs`]
    /// does, with `--split-gaps`.
    ///
    /// # Errors
    /// Those of [`crate::app::read_logs`].
    pub fn read_logs(
        &self,
        paths: &[PathBuf],
        csv: &CsvOptions,
        unique: bool,
    ) -> crate::Result<Vec<Vec<Experiment>>> {
        crate::app::read_logs(paths, csv, self.split_gaps, unique)
    }
}
