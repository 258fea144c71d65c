//! `greybox fit`: read the logs, fit, print the table and write the JSON report.

use super::args::{FitArgs, FormatArg};
use super::output;
use crate::app::{FitOutcome, FitRequest, fit_experiments, plan};
use crate::data::Staged;
use crate::estimate::FitResult;
use crate::report::Document;
use std::time::Instant;

/// Runs `greybox fit`; `Ok(false)` when the report was written but the result is not
/// trustworthy (not converged, or an untrusted warning) and `--allow-unconverged` is off.
pub fn run_fit(a: &FitArgs) -> crate::Result<bool> {
    let t0 = Instant::now();
    for (flag, given) in [("--summary", a.summary.is_some()), ("--trend", a.trend.is_some())] {
        if given {
            return Err(crate::Error::InvalidOption {
                option: flag.into(),
                reason: "belongs to a batch (--each DIR_OR_GLOB); one fit writes --json and --plot".into(),
            });
        }
    }
    // Fail before the fit, not after it, when the report cannot be written.
    output::check_all(
        &[
            ("--json", a.json.as_deref()),
            ("--plot", a.plot.as_deref()),
            ("--residuals", a.residuals.as_deref()),
        ],
        &a.logs,
    )?;
    let quiet = a.quiet || a.json.as_ref().is_some_and(|p| p.as_os_str() == "-");
    let request = FitRequest::from(a);
    let plan = plan(&request)?;
    crate::app::check_paths(&a.logs)?;
    let logs: Vec<_> = a.columns.read_logs(&a.logs, &plan.csv, true)?.into_iter().flatten().collect();
    let read_s = t0.elapsed().as_secs_f64();
    let fitted = fit_experiments(&request, &plan, &logs, t0, read_s)?;
    // Every output file staged, the report printed, then all renamed at once.
    let mut staged = Staged::new();
    if let FitOutcome::Pem(fit) = &fitted.outcome {
        super::plots::fit_outputs(&mut staged, a.plot.as_deref(), a.residuals.as_deref(), fit, &logs)?;
    }
    if !quiet {
        print_report(a.format, &fitted.document, &fitted.json)?;
    }
    if let Some(path) = &a.json {
        output::write(&mut staged, path, &fitted.json)?;
    }
    staged.commit()?;
    Ok(trusted(fitted.report(), a.allow_unconverged))
}

/// Whether `report` is trusted, saying why not on stderr; `allow` (--allow-unconverged)
/// lets an untrusted one pass.
fn trusted(report: &FitResult, allow: bool) -> bool {
    let trusted = report.trusted();
    if !trusted {
        eprintln!(
            "warning: the estimates are not to be trusted ({}){}",
            report.untrusted_codes().join(", "),
            if allow { "" } else { "; exit code 3 (--allow-unconverged: 0)" }
        );
    }
    trusted || allow
}

/// Prints the report on stdout in the `--format` asked for.
///
/// # Errors
/// [`crate::Error::Write`] when stdout cannot take it (not a closed pipe).
fn print_report(format: FormatArg, doc: &Document, json: &str) -> crate::Result<()> {
    super::output::stdout(&match format {
        FormatArg::Table => doc.to_text(),
        FormatArg::Markdown => doc.to_markdown(),
        FormatArg::Json => format!("{json}\n"),
    })
}
