//! The report of an instrumental-variables fit (`super::iv`): the output-error fit's report
//! with the IV estimate, its covariance and intervals (restricted where the batches give
//! them, `estimate::restricted`), the derived quantities through those intervals, and the
//! warnings the IV estimate replaces.

use crate::estimate::iv::IvCovariance;
use crate::estimate::{ParameterEstimate, SolverReport, Termination};
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::model::kind::{MotorKind, derived};

/// The IV estimate, its covariance, the refinements made and whether they converged.
pub(super) type Solved = (Vec<f64>, IvCovariance, usize, bool);

/// The output-error report `oe` with the IV estimate θ, its covariance and iterations, and
/// the `imprecise` verdict of the accuracy `precision` states on its intervals; `floor`, a
/// note that the output-error fit's `poor_fit` is the input noise's floor, which drops it.
pub(super) fn report(
    oe: PmsmFit,
    (theta, cov, iterations, converged): Solved,
    fit_s: f64,
    precision: Option<&[crate::estimate::PrecisionTarget]>,
    floor: Option<String>,
) -> PmsmFit {
    let n = theta.len();
    let se: Vec<f64> = (0..n).map(|j| cov.cov[(j, j)].max(0.0).sqrt()).collect();
    let ci: Vec<[f64; 2]> =
        (0..n).map(|j| [theta[j] + cov.ci95_offsets[j][0], theta[j] + cov.ci95_offsets[j][1]]).collect();
    let mut parameters: Vec<ParameterEstimate> = oe.report.parameters.clone();
    for (j, p) in parameters.iter_mut().take(n).enumerate() {
        let start = p.value;
        *p = ParameterEstimate {
            value: theta[j],
            std_error: se[j],
            std_error_white: cov.cov_white[(j, j)].max(0.0).sqrt(),
            ci95: ci[j],
            // The error index belongs to the output-error criterion.
            error_index_percent: f64::NAN,
            at_bound: false,
            start,
            ..p.clone()
        };
    }
    let correlation = (0..n).map(|a| (0..n).map(|b| cov.cov[(a, b)] / (se[a] * se[b])).collect()).collect();
    let termination = if converged { Termination::StepTolerance } else { Termination::MaxIterations };
    let solver = SolverReport {
        name: "iv".into(),
        iterations: iterations as u64,
        termination: termination.to_string(),
        success: converged,
        reason: termination,
        evaluations: iterations as u64 + 1,
        accepted_iterations: iterations as u64,
        trace: Vec::new(),
    };
    let mut notes = oe.report.notes.clone();
    let kind = if n == MotorKind::Spm.parameter_names().len() { MotorKind::Spm } else { MotorKind::Ipm };
    let start: Vec<String> =
        oe.report.parameters.iter().take(n).map(|p| format!("{} {:.6e}", p.name, p.value)).collect();
    notes.push(format!(
        "instrumental variables on the {}, instruments from the model's simulated currents one interval back, \
         {iterations} refinements from the output-error estimate ({}); goodness of fit and residual checks are \
         the output-error fit's",
        match kind {
            MotorKind::Spm => "exact inverse model (voltage equation errors)",
            MotorKind::Ipm => "one-step current equation (the exact step from the measured current)",
        },
        start.join(", ")
    ));
    // The input noise the output-error fit was told of is what this method is for.
    let mut warnings: Vec<_> = oe
        .report
        .warnings
        .iter()
        .filter(|w| {
            let replaced =
                ["input_noise", "voltage_noise_bias", "undetermined", "imprecise", "coloured_residuals"];
            !replaced.contains(&w.code.as_str()) && (floor.is_none() || w.code != "poor_fit")
        })
        .cloned()
        .collect();
    // The output-error intervals' verdicts replaced by these intervals'.
    warnings.extend(crate::estimate::gate::undetermined_warning(&kind.undetermined(&parameters)));
    warnings.extend(crate::estimate::colour::unbatched(&cov.uncertainty, &oe.report.fit, &parameters, true));
    warnings.extend(precision.and_then(|targets| {
        crate::estimate::imprecise(
            &parameters,
            cov.uncertainty.dof,
            targets,
            "--precision",
            super::workflow::PRECISION_ADVICE,
        )
    }));
    notes.extend(floor);
    let unbounded = "the batches' restricted interval is unbounded (too few carry it): ± t·std_error instead";
    notes.extend(cov.unbounded.iter().map(|&j| format!("{}: {unbounded}", parameters[j].name)));
    if !converged {
        warnings.push(crate::estimate::Warning::untrusted(
            "not_converged",
            format!("the instrumental-variable iteration did not settle in {iterations} refinements"),
        ));
    }
    let report = crate::estimate::FitResult {
        derived: derived(
            kind,
            oe.pole_pairs,
            &theta,
            &se,
            cov.cov[(0, n - 1)] / (se[0] * se[n - 1]),
            Some(&ci),
        )
        .into_iter()
        .map(|d| d.with_interval(cov.t_quantile()))
        .collect(),
        parameters,
        correlation,
        uncertainty: cov.uncertainty.clone(),
        solver,
        parameter_trace: Vec::new(),
        notes,
        warnings,
        timing: crate::estimate::Timing { fit_s, total_s: fit_s, solve_s: None, ..oe.report.timing.clone() },
        // The initial states and the error-index verdicts are the output-error criterion's;
        // the information matrix's singular values still describe the data.
        initial_states: Vec::new(),
        diagnostics: crate::estimate::diagnostics::Diagnostics {
            poorly_determined: Vec::new(),
            correlated: Vec::new(),
            advice: Vec::new(),
            ..oe.report.diagnostics.clone()
        },
        ..oe.report.clone()
    };
    PmsmFit { report, start_comparison: Vec::new(), ..oe }
}
