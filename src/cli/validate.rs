//! `greybox validate`: a saved fit against logs it was not fitted on (MATLAB's `compare`).

use super::args::ColumnArgs;
use super::output;
use crate::app::{ValidateRequest, validate, validation_json};
use crate::data::Staged;
use crate::pmsm::VoltageHold;
use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// Arguments of `greybox validate`.
#[derive(Args, Debug)]
pub struct ValidateArgs {
    /// Drive logs to validate on (CSV, plain or gzip), each compared on its own.
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// The JSON report of a fit (`greybox fit --json`).
    #[arg(long)]
    pub params: PathBuf,
    /// Pole pairs, when the report does not give them (a least-squares report).
    #[arg(long, short = 'p')]
    pub pole_pairs: Option<u32>,
    /// Voltage hold, overriding the report's.
    #[arg(long, value_enum)]
    pub hold: Option<ValidateHold>,
    /// Write the comparison (metrics per log) as JSON to this file ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write measured and simulated outputs of each log as CSV into this folder
    /// (`<log>.compare.csv`: t, id, id_sim, iq, iq_sim), for plotting.
    #[arg(long)]
    pub compare_dir: Option<PathBuf>,
    /// Write the compare plot (SVG) to this file: measured against simulated outputs with
    /// the speed, residuals with ±2σ, their autocorrelation and the fit per log.
    #[arg(long, value_name = "PATH.svg")]
    pub plot: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(long, short = 'q')]
    pub quiet: bool,
    /// The log-reading flags (columns, units, window, limits).
    #[command(flatten)]
    pub columns: ColumnArgs,
}

/// The voltage hold of a validation (`--hold`): `dq` or `stator`.
// The values' clap docs would become `--help` text of their own: the enum's doc says them.
#[allow(missing_docs)]
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ValidateHold {
    Dq,
    Stator,
}

/// Runs `greybox validate`: the saved fit simulated on every log, the metrics on stdout,
/// the JSON, the comparison CSVs and the plot where asked.
///
/// # Errors
/// An output that cannot be written, an unreadable or invalid `--params`, an unreadable
/// log, a simulation that fails.
pub fn run_validate(a: &ValidateArgs) -> crate::Result<()> {
    let inputs: Vec<PathBuf> = a.logs.iter().chain([&a.params]).cloned().collect();
    output::check_all(&[("--json", a.json.as_deref()), ("--plot", a.plot.as_deref())], &inputs)?;
    if let Some(dir) = a.compare_dir.as_ref().filter(|d| !d.is_dir()) {
        return Err(crate::Error::InvalidOption {
            option: "compare-dir".into(),
            reason: format!("{} is not a folder", dir.display()),
        });
    }
    let (saved, logs, comparisons) = validate(&a.logs, &ValidateRequest::from(a))?;
    let quiet = a.quiet || a.json.as_ref().is_some_and(|p| p.as_os_str() == "-");
    if !quiet {
        super::output::stdout(
            &(format!(
                "model {} with {} pole pairs, {} hold, θ = {:?}",
                saved.kind.model_name(),
                saved.pole_pairs,
                saved.hold,
                saved.theta
            ) + "\n"),
        )?;
        for c in &comparisons {
            let m = &c.metrics;
            let per = |v: &[f64], d: usize| {
                m.outputs.iter().zip(v).map(|(n, x)| format!("{n} {x:.d$}")).collect::<Vec<_>>().join(", ")
            };
            let white: Vec<String> = m
                .outputs
                .iter()
                .zip(&m.whiteness)
                .map(|(n, w)| format!("{n} {:.0} %", 100.0 * w.fraction_outside))
                .collect();
            super::output::stdout(
                &(format!(
                    "{}: fit [%] {}; rms residual {}; FPE {:.4e}, AIC {:.1}; lags outside the whiteness bound: {}",
                    c.experiment,
                    per(&m.fit_percent, 4),
                    m.outputs
                        .iter()
                        .zip(&m.rms_residual)
                        .enumerate()
                        .map(|(i, (n, x))| format!(
                            "{n} {}",
                            crate::report::eng::format_eng(*x, c.unit(i), 5)
                        ))
                        .collect::<Vec<_>>()
                        .join(", "),
                    m.fpe,
                    m.aic,
                    white.join(", ")
                ) + "\n"),
            )?;
        }
    }
    let mut staged = Staged::new();
    if let Some(path) = &a.plot {
        super::plots::compare_plot(&mut staged, path, &comparisons, &logs)?;
    }
    if let Some(dir) = &a.compare_dir {
        for c in &comparisons {
            let path = dir.join(format!("{}.compare.csv", c.experiment));
            output::write(&mut staged, &path, c.to_csv().trim_end())?;
        }
    }
    if let Some(path) = &a.json {
        output::write(&mut staged, path, &validation_json(&saved, &comparisons))?;
    }
    staged.commit()
}

impl From<&ValidateArgs> for ValidateRequest {
    /// The request of the flags (`--json`, `--compare-dir`, `--plot` and `--quiet` are the
    /// command line's outputs, not the request's).
    fn from(a: &ValidateArgs) -> Self {
        ValidateRequest {
            params: a.params.clone(),
            pole_pairs: a.pole_pairs,
            hold: a.hold.map(|h| match h {
                ValidateHold::Dq => VoltageHold::Dq,
                ValidateHold::Stator => VoltageHold::Stator,
            }),
            reading: a.columns.reading(),
        }
    }
}
