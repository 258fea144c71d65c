//! `greybox fluxmap`: the saturation model (Hinkkanen et al., IEEE Trans. Ind. Appl. 53(3)
//! 2017) fitted to a measured flux map, its coefficients with standard errors, the residual
//! against the map's range and the inductances at a few operating points (issue 33).

use super::output;
use crate::Error;
use crate::pmsm::{FluxMapOptions, SaturationExponents, fit_flux_map, read_flux_map};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `greybox fluxmap`.
#[derive(Args, Debug)]
#[command(after_help = "A flux map is a NumPy .npz with the complex arrays i_s_dq [A] and psi_s_dq [V s] \
(d + j q, amplitude-invariant), or a CSV with the columns i_d, i_q, psi_d, psi_q. See docs/saturation.md.")]
pub struct FluxMapArgs {
    /// The flux map (.npz or .csv[.gz]).
    pub map: PathBuf,
    /// The exponents S,T,U,V of the model (default: chosen from 1..9 × 1..9 × 0..2 × 0..2).
    #[arg(long, value_delimiter = ',', num_args = 4, value_name = "S,T,U,V")]
    pub exponents: Option<Vec<u32>>,
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
    let map = read_flux_map(&a.map)?;
    let fit = fit_flux_map(&map, &FluxMapOptions { exponents, ..Default::default() })?;
    let untrusted = fit.check.iter().flat_map(|c| &c.warnings).map(|w| w.code.clone()).collect();
    Ok(output::Outcome::new(fit.to_string(), &fit, untrusted))
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
