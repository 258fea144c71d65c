//! A measured flux map fitted by the saturation model (Hinkkanen et al., IEEE Trans. Ind.
//! Appl. 53(3) 2017): what `greybox fluxmap` and Python's `fluxmap` ask ([`FluxMapRequest`])
//! and its report ([`fluxmap`]).

use super::report::Report;
use crate::error::{Error, Result};
use crate::pmsm::{
    FluxMapColumns, FluxMapFit, FluxMapOptions, LogSource, SaturationExponents, TorqueCheck, fit_flux_map,
    read_flux_map_from, torque_check,
};
use serde::Serialize;

/// A flux-map fit as asked for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FluxMapRequest {
    /// The model's exponents; `None`: chosen from 1..9 × 1..9 × 0..2 × 0..2.
    pub exponents: Option<SaturationExponents>,
    /// The map's columns (a CSV, Parquet or Arrow map) and a CSV's delimiter.
    pub columns: FluxMapColumns,
    /// Pole pairs n_p, for the torque `1.5 n_p (ψ_d i_q − ψ_q i_d)` \[N m\] compared with a
    /// measured one.
    pub pole_pairs: Option<u32>,
}

/// The fit of the flux map at `map` (`.npz` with `i_s_dq` \[A\] and `psi_s_dq` \[V s\], or a
/// table with one point per row) as `r` asks, and its report: coefficients with standard
/// errors, the rms flux residual against the map's range, inductances, the no-load flux and
/// incremental inductances checked against the map, and the measured torque against the
/// model's when the map has one and `r.pole_pairs` is given. Untrusted when the no-load
/// flux or the inductances miss the map's own values (`no_load_flux`,
/// `inductance_mismatch`); a coefficient at its bound zero is a finding, not a fault.
///
/// # Errors
/// A bad path ([`super::super::check_paths`]), an unreadable map (a missing column as
/// [`Error::InvalidOption`] naming its `--col-*` flag), a failed fit.
pub fn fluxmap(map: LogSource<'_>, r: &FluxMapRequest) -> Result<Report> {
    if let LogSource::Path(path) = map {
        crate::app::check_paths(&[path.to_path_buf()])?;
    }
    let columns = &r.columns;
    let read = read_flux_map_from(map, columns).map_err(|e| match e {
        Error::MissingColumn { column, available, .. } => Error::InvalidOption {
            option: flag_of(columns, &column).into(),
            reason: format!(
                "no column `{column}` in the map's header ({available}): name the column with this option"
            ),
        },
        e => e,
    })?;
    let fit = fit_flux_map(&read.map, &FluxMapOptions { exponents: r.exponents, ..Default::default() })?;
    // A torque that cannot be compared is a note, not a failed flux-map fit.
    let (torque, torque_note) = match (&read.torque, r.pole_pairs) {
        (Some(t), Some(n_p)) => match torque_check(&read.map, &fit, t, n_p) {
            Ok(check) => (Some(check), None),
            Err(e) => (
                None,
                Some(format!("the measured torque (--col-torque {}) is not compared: {e}", columns.torque)),
            ),
        },
        (Some(_), None) => (
            None,
            Some(format!(
                "the map has a measured torque (`{}`); give the pole pairs (-p) to compare it with the model's",
                columns.torque
            )),
        ),
        (None, Some(_)) => (
            None,
            Some(format!(
                "-p compares a measured torque, and the map has no column `{}` (--col-torque; a Parquet or Arrow \
                 one is read only without gaps, an .npz holds none)",
                columns.torque
            )),
        ),
        (None, None) => (None, None),
    };
    let untrusted = fit.check.iter().flat_map(|c| &c.warnings).map(|w| w.code.clone()).collect();
    let mut text = String::new();
    if let Some(first) = read.first_skipped {
        text = format!(
            "{} of the map's {} points left out for a missing value (empty, NaN or inf), the first at point {first}\n",
            read.skipped,
            read.skipped + read.map.len()
        );
    }
    text += &fit.to_string();
    if let Some(t) = &torque {
        text += &t.to_string();
    }
    if let Some(n) = &torque_note {
        text += &format!("note: {n}\n");
    }
    let report = Json { skipped_points: read.skipped, fit: &fit, torque: torque.as_ref() };
    Ok(Report::new(text, &report, untrusted))
}

/// The JSON report of a flux-map fit: the fit and the points the reader left out.
#[derive(Serialize)]
struct Json<'a> {
    /// Points left out for a missing value.
    skipped_points: usize,
    #[serde(flatten)]
    fit: &'a FluxMapFit,
    /// The measured torque against the model's (with a torque column and the pole pairs).
    #[serde(skip_serializing_if = "Option::is_none")]
    torque: Option<&'a TorqueCheck>,
}

/// The `--col-*` flag of the map column `column`.
fn flag_of(c: &FluxMapColumns, column: &str) -> &'static str {
    match column {
        x if x == c.i_d => "--col-id",
        x if x == c.i_q => "--col-iq",
        x if x == c.psi_d => "--col-psid",
        x if x == c.torque => "--col-torque",
        _ => "--col-psiq",
    }
}
