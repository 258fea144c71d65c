//! `greybox fluxmap`: the saturation model (Hinkkanen et al., IEEE Trans. Ind. Appl. 53(3)
//! 2017) fitted to a measured flux map, its coefficients with standard errors, the residual
//! against the map's range and the inductances at a few operating points (issue 33).

use super::output;
use crate::Error;
use crate::data::Delimiter;
use crate::pmsm::{
    FluxMapColumns, FluxMapFit, FluxMapOptions, SaturationExponents, TorqueCheck, fit_flux_map,
    read_flux_map_with, torque_check,
};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;

/// Arguments of `greybox fluxmap`.
#[derive(Args, Debug)]
#[command(after_help = "A flux map is a NumPy .npz with the complex arrays i_s_dq [A] and psi_s_dq [V s] \
(d + j q, amplitude-invariant), or a CSV (Parquet, Arrow) with one point per row and the columns i_d, i_q, psi_d, \
psi_q (renamed with --col-*). Points with a missing value (empty, NaN) are left out and counted. A measured \
torque column (`torque`, or --col-torque) is compared with the model's torque 1.5 n_p (psi_d i_q - psi_q i_d) when \
-p is given. See docs/saturation.md.")]
pub struct FluxMapArgs {
    /// The flux map (.npz or .csv[.gz]).
    pub map: PathBuf,
    /// The exponents S,T,U,V of the model (default: chosen from 1..9 × 1..9 × 0..2 × 0..2).
    #[arg(long, value_delimiter = ',', num_args = 4, value_name = "S,T,U,V")]
    pub exponents: Option<Vec<u32>>,
    /// Column of the d-axis current [A, peak dq] in a CSV, Parquet or Arrow map.
    #[arg(long, default_value = "i_d", value_name = "NAME")]
    pub col_id: String,
    /// Column of the q-axis current [A, peak dq].
    #[arg(long, default_value = "i_q", value_name = "NAME")]
    pub col_iq: String,
    /// Column of the d-axis flux linkage [V s].
    #[arg(long, default_value = "psi_d", value_name = "NAME")]
    pub col_psid: String,
    /// Column of the q-axis flux linkage [V s].
    #[arg(long, default_value = "psi_q", value_name = "NAME")]
    pub col_psiq: String,
    /// Column of a measured torque [N m] (optional: compared with the model's when -p is given).
    #[arg(long, default_value = "torque", value_name = "NAME")]
    pub col_torque: String,
    /// Pole pairs n_p, for the torque 1.5 n_p (ψ_d i_q − ψ_q i_d) compared with a measured one.
    #[arg(long, short = 'p', value_parser = clap::value_parser!(u32).range(1..))]
    pub pole_pairs: Option<u32>,
    /// Field delimiter of a CSV map: `,` `;` `tab` (or `\t`) `|`.
    #[arg(long, default_value = ",", value_parser = |s: &str| s.parse::<Delimiter>().map_err(|e| e.to_string()))]
    pub delimiter: Delimiter,
    /// The report's outputs.
    #[command(flatten)]
    pub report: output::ReportArgs,
}

/// Runs `greybox fluxmap`; whether the fit is trusted (exit 3 if not).
///
/// # Errors
/// An unreadable map, exponents that are not four integers, a failed fit, an output that
/// cannot be written.
pub fn run_fluxmap(a: &FluxMapArgs) -> crate::Result<bool> {
    a.report.run(std::slice::from_ref(&a.map), "flux-map fit", || fluxmap_outcome(a))
}

/// The fit of `greybox fluxmap` and its reports, nothing printed or written. Untrusted (exit
/// 3) when the reported no-load flux or inductances miss the map's own values
/// (`no_load_flux`, `inductance_mismatch`); a coefficient at its bound zero is a finding,
/// not a fault.
///
/// # Errors
/// As [`run_fluxmap`] but for the output.
pub fn fluxmap_outcome(a: &FluxMapArgs) -> crate::Result<output::Outcome> {
    let exponents = a.exponents.as_deref().map(parse_exponents).transpose()?;
    let columns = FluxMapColumns {
        i_d: a.col_id.clone(),
        i_q: a.col_iq.clone(),
        psi_d: a.col_psid.clone(),
        psi_q: a.col_psiq.clone(),
        delimiter: a.delimiter,
        torque: a.col_torque.clone(),
    };
    let read = read_flux_map_with(&a.map, &columns).map_err(|e| match e {
        Error::MissingColumn { column, available, .. } => Error::InvalidOption {
            option: flag_of(&columns, &column).into(),
            reason: format!(
                "no column `{column}` in the map's header ({available}): name the column with this flag"
            ),
        },
        e => e,
    })?;
    let fit = fit_flux_map(&read.map, &FluxMapOptions { exponents, ..Default::default() })?;
    // A torque that cannot be compared is a note, not a failed flux-map fit.
    let (torque, torque_note) = match (&read.torque, a.pole_pairs) {
        (Some(t), Some(n_p)) => match torque_check(&read.map, &fit, t, n_p) {
            Ok(check) => (Some(check), None),
            Err(e) => (
                None,
                Some(format!("the measured torque (--col-torque {}) is not compared: {e}", a.col_torque)),
            ),
        },
        (Some(_), None) => (
            None,
            Some(format!(
                "the map has a measured torque (`{}`); give the pole pairs (-p) to compare it with the model's",
                a.col_torque
            )),
        ),
        (None, Some(_)) => (
            None,
            Some(format!(
                "-p compares a measured torque, and the map has no column `{}` (--col-torque; a Parquet or Arrow \
                 one is read only without gaps, an .npz holds none)",
                a.col_torque
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
    let report = Report { skipped_points: read.skipped, fit: &fit, torque: torque.as_ref() };
    Ok(output::Outcome::new(text, &report, untrusted))
}

/// The JSON report of `greybox fluxmap`: the fit and the points the reader left out.
#[derive(Serialize)]
struct Report<'a> {
    /// Points left out for a missing value.
    skipped_points: usize,
    #[serde(flatten)]
    fit: &'a FluxMapFit,
    /// The measured torque against the model's (with a torque column and -p).
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

/// The exponents `S,T,U,V` of `--exponents`.
///
/// # Errors
/// [`Error::InvalidOption`] (`--exponents`) unless four integers with `S, T ≥ 1`.
pub fn parse_exponents(values: &[u32]) -> crate::Result<SaturationExponents> {
    match *values {
        [s, t, u, v] if s >= 1 && t >= 1 => Ok(SaturationExponents { s, t, u, v }),
        _ => Err(Error::InvalidOption {
            option: "--exponents".into(),
            reason: format!("{values:?}: give four integers S,T,U,V with S, T ≥ 1, e.g. --exponents 4,2,1,0"),
        }),
    }
}
