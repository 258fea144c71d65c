//! `greybox fluxmap`: the saturation model (Hinkkanen et al., IEEE Trans. Ind. Appl. 53(3)
//! 2017) fitted to a measured flux map, its coefficients with standard errors, the residual
//! against the map's range and the inductances at a few operating points (issue 33).

use super::output;
use crate::app::{FluxMapRequest, exponents, fluxmap};
use crate::data::Delimiter;
use crate::pmsm::FluxMapColumns;
use crate::pmsm::LogSource;
use clap::Args;
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
    #[arg(long, value_delimiter = ',', value_name = "S,T,U,V")]
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

impl TryFrom<&FluxMapArgs> for FluxMapRequest {
    type Error = crate::Error;

    /// The request of these flags.
    ///
    /// # Errors
    /// [`crate::Error::InvalidOption`] (`--exponents`) for bad exponents.
    fn try_from(a: &FluxMapArgs) -> crate::Result<Self> {
        Ok(Self {
            exponents: a.exponents.as_deref().map(exponents).transpose()?,
            columns: FluxMapColumns {
                i_d: a.col_id.clone(),
                i_q: a.col_iq.clone(),
                psi_d: a.col_psid.clone(),
                psi_q: a.col_psiq.clone(),
                delimiter: a.delimiter,
                torque: a.col_torque.clone(),
            },
            pole_pairs: a.pole_pairs,
        })
    }
}

/// Runs `greybox fluxmap`; whether the fit is trusted (exit 3 if not: [`fluxmap`]).
///
/// # Errors
/// An unreadable map, exponents that are not four integers, a failed fit, an output that
/// cannot be written.
pub fn run_fluxmap(a: &FluxMapArgs) -> crate::Result<bool> {
    let r = FluxMapRequest::try_from(a)?;
    a.report.run(std::slice::from_ref(&a.map), "flux-map fit", || fluxmap(LogSource::Path(&a.map), &r))
}
