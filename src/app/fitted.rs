//! One fit of logs already read, as data: the JSON report, its document (table) and the
//! fit itself, for the command line to print and write, and for the Python package to hand
//! over.

use super::plan::{Plan, fit_logs, pole_pairs};
use super::request::FitRequest;
use crate::Experiment;
use crate::estimate::{FitResult, PemOptions, Timing};
use crate::pmsm::{LinearOptions, PmsmFit, PmsmFitOptions, fit_pmsm, weighted_least_squares};
use crate::report::Document;
use std::time::Instant;

/// What the fit produced: a prediction-error fit (with everything the plots need) or the
/// report of a linear least-squares regression (`--method ls`).
#[derive(Debug)]
pub enum FitOutcome {
    /// `--method pem` or `iv`: the fit with its report.
    Pem(Box<PmsmFit>),
    /// `--method ls`: the regression's report.
    Ls(Box<FitResult>),
}

/// A finished fit: the JSON report (`greybox fit --json`), its document (the table `greybox
/// fit` prints) and the outcome.
#[derive(Debug)]
pub struct Fitted {
    /// The JSON report, byte for byte what `--json` writes (without its final newline).
    pub json: String,
    /// The report as a document (table, Markdown).
    pub document: Document,
    /// The fit or the regression.
    pub outcome: FitOutcome,
}

impl Fitted {
    /// The report: the fit's, or the regression's.
    pub fn report(&self) -> &FitResult {
        match &self.outcome {
            FitOutcome::Pem(fit) => &fit.report,
            FitOutcome::Ls(report) => report,
        }
    }
}

/// Fits the experiments `logs` as `greybox fit` does with the request `a` planned into `plan`
/// (read from `t0` on, in `read_s` seconds): the prediction-error fit of [`fit_logs`], or for
/// `--method ls` the weighted least-squares regression with the prediction-error fit's
/// disagreement as warnings.
///
/// # Errors
/// Those of [`fit_logs`], of the `--weighting` rule and of the regression.
pub fn fit_experiments(
    a: &FitRequest,
    plan: &Plan,
    logs: &[Experiment],
    t0: Instant,
    read_s: f64,
) -> crate::Result<Fitted> {
    if let Some((options, search, estimator)) = &plan.pem {
        let fit = fit_logs(a.pole_pairs, options, *search, *estimator, logs, t0, read_s)?;
        let json = fit.to_json();
        let document = fit.document(plan.report_options);
        return Ok(Fitted { json, document, outcome: FitOutcome::Pem(Box::new(fit)) });
    }
    let t1 = Instant::now();
    let rule = a.weighting.rule()?;
    let opts = LinearOptions { prefilter: a.prefilter, ..LinearOptions::default() };
    let (n_p, _) = pole_pairs(a.pole_pairs, logs, plan.kind, None)?;
    let ls = weighted_least_squares(logs, n_p, plan.kind, rule.as_ref(), &opts)?;
    let names: Vec<String> = logs.iter().map(|e| e.name().to_string()).collect();
    let report = ls.report(&names, n_p, t1.elapsed().as_secs_f64());
    // The prediction-error fit of the same logs tells whether noise biased the regression.
    let pem = PmsmFitOptions { model: plan.kind, ..PmsmFitOptions::new(n_p) };
    let warnings = match fit_pmsm(
        logs,
        &PmsmFitOptions { pem: PemOptions { progress: false, ..pem.pem.clone() }, ..pem },
    ) {
        Ok(fit) => ls.disagreement(&fit.report).into_iter().collect(),
        Err(_) => Vec::new(),
    };
    let timing = Timing { read_s, total_s: t0.elapsed().as_secs_f64(), ..report.timing.clone() };
    let report = FitResult { timing, warnings, ..report };
    let json = report.to_json();
    let k = |n: &str| report.parameter(n).map(|p| p.value);
    let kt = report.derived("k_t").map(|q| q.value);
    let conventions = crate::pmsm::conventions(k("k_e"), kt, k("l_d").is_some(), plan.report_options);
    let document = report.document(&conventions);
    Ok(Fitted { json, document, outcome: FitOutcome::Ls(Box::new(report)) })
}
