//! The steady-state fit's report ([`super::steady`]): the estimate as the generic report
//! every fit gives (parameters with intervals, the control period as a nuisance
//! parameter, derived quantities and temperatures, diagnostics, goodness of fit over the
//! steady samples, the IV iterations as the solver).

use crate::data::Experiment;
use crate::estimate::diagnostics::{DiagnosticThresholds, diagnose};
use crate::estimate::t_quantile_975;
use crate::estimate::{
    FitResult, FitStatistics, ParameterEstimate, SolverReport, Termination, Timing, metrics,
};
use crate::model::DerivedEstimate;
use crate::pmsm::linear::{PERIOD_TERM, SteadyEstimate, SteadyOptions, steady_advice};
use crate::pmsm::model::interval::SQRT_2_3;
use crate::pmsm::model::kind::derived;
use crate::pmsm::options::PmsmFitOptions;
use nalgebra::DMatrix;

/// The estimate `est` of `experiments` as the generic report (parameters with intervals,
/// derived quantities and temperatures, diagnostics, goodness of fit over the steady
/// samples, the IV iterations as the solver), `fit_s` \[s\] the time it took, `widening`
/// the notes on intervals widened (by the parts' spread, by the truncation error).
pub(super) fn report(
    est: &SteadyEstimate,
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    fit_s: f64,
    widening: Vec<String>,
) -> FitResult {
    let n = est.theta.len();
    let label = |j: usize| match est.experiment[j].is_none() && est.names[j] == PERIOD_TERM {
        true => PERIOD_SHOWN.to_string(),
        false => super::steady_checks::label(est, j),
    };
    let relative: Vec<f64> = (0..n).map(|j| 100.0 * est.std_error[j] / est.theta[j].abs()).collect();
    let parameters: Vec<ParameterEstimate> = (0..n)
        .map(|j| {
            let p = ParameterEstimate {
                name: est.names[j].clone(),
                unit: est.units[j].clone(),
                value: est.theta[j],
                std_error: est.std_error[j],
                std_error_white: est.std_error_white[j],
                ci95: [est.theta[j] - est.ci95[j], est.theta[j] + est.ci95[j]],
                // The error index belongs to the output-error criterion.
                error_index_percent: f64::NAN,
                fixed: false,
                nuisance: false,
                at_bound: false,
                experiment: est.experiment[j].clone(),
                start: est.theta[j],
            };
            if est.names[j] == PERIOD_TERM { control_period(p) } else { p }
        })
        .collect();
    let cov = DMatrix::from_fn(n, n, |a, b| est.correlation[a][b] * est.std_error[a] * est.std_error[b]);
    // Relative information: by θ; the period term h_c2 by 12/ω_e² at the logs' top
    // electrical speed, where its back-EMF term (ω_e h_c)²/12 is the whole back-EMF, so that
    // its relative error is that of the back-EMF it corrects, as K_e's is (its estimate is
    // about 0 on a log whose voltage is held in dq; scaled by its own standard error, a
    // precise fit of such a log read as singular: condition 2.5e12 on every 80th row of a
    // shared 8 kHz log of moves whose estimates lie within 1.1 standard errors).
    let w_e_top = crate::pmsm::log::DqLogs::try_new(experiments)
        .map_or(0.0, |dq| dq.views().iter().flat_map(|v| v.w_m().iter()).fold(0.0f64, |a, w| a.max(w.abs())))
        * f64::from(options.pole_pairs);
    let size = |j: usize| match (est.names[j] == PERIOD_TERM, w_e_top > 0.0 && w_e_top.is_finite()) {
        (true, true) => 12.0 / (w_e_top * w_e_top),
        (true, false) => est.theta[j].abs().max(est.std_error[j]),
        (false, _) => est.theta[j],
    };
    let info_rel = cov
        .try_inverse()
        .map(|m| DMatrix::from_fn(n, n, |a, b| m[(a, b)] * size(a) * size(b)))
        .unwrap_or_else(|| DMatrix::from_element(n, n, f64::NAN));
    let labels: Vec<String> = (0..n).map(label).collect();
    let kind = est.kind;
    let diagnostics = diagnose(
        &info_rel,
        &labels,
        &relative,
        &est.correlation,
        &DiagnosticThresholds::default(),
        &|name| Some(format!("{name} not identifiable at steady state: {}", steady_advice(kind, name))),
        &|a, b| kind.pair_advice(a, b),
    );
    let rows = 2 * est.steady_samples;
    let sse: f64 = est.rms_residual.iter().map(|r| r * r * est.steady_samples as f64).sum();
    let fit = FitStatistics {
        outputs: vec!["ud".into(), "uq".into()],
        output_units: vec!["V".into(), "V".into()],
        fit_percent: est.fit_percent.to_vec(),
        rms_residual: est.rms_residual.to_vec(),
        loss: 0.5 * sse,
        mse: sse / rows as f64,
        aic: metrics::aic(sse, rows, n),
        bic: metrics::bic(sse, rows, n),
        fpe: metrics::fpe(sse, rows, n),
        whiteness: est.whiteness.clone(),
        samples: est.steady_samples,
        dof: rows.saturating_sub(n),
        counted: None,
        horizon: None,
    };
    let reason = if est.converged { Termination::StepTolerance } else { Termination::MaxIterations };
    let hc = est.control_period.map_or_else(
        || "continuous (no --control-period: see the note on the control period)".into(),
        |h| {
            format!(
                "at the drive's control period {h:e} s (exact periodic steady state of the stator-held step)"
            )
        },
    );
    FitResult {
        model: format!("{}_steady", kind.model_name()),
        experiments: experiments.iter().map(|e| e.name().to_string()).collect(),
        derived: derived_all(est, options),
        parameters,
        initial_states: Vec::new(),
        diagnostics,
        fit,
        correlation: est.correlation.clone(),
        correlation_names: labels,
        uncertainty: est.uncertainty.clone(),
        solver: SolverReport {
            name: "iv".into(),
            iterations: est.iterations as u64,
            termination: reason.to_string(),
            success: est.converged,
            reason,
            evaluations: est.iterations as u64 + 1,
            accepted_iterations: est.iterations as u64,
            trace: Vec::new(),
        },
        parameter_trace: Vec::new(),
        timing: Timing { read_s: 0.0, fit_s, total_s: fit_s, solve_s: None },
        notes: std::iter::once(format!(
            "steady-state equations u_d = R_s i_d + L_d di_d/dt − ω_e L_q i_q, u_q = R_s i_q + L_q di_q/dt + ω_e L_d \
             i_d + √(2/3) ω_m K_e on the {} smooth samples of {} (each current's second differences at k − 1, k, \
             k + 1 within {}·√6 σ_i, or at k alone where a note says so; di/dt by central differences at the log's \
             rate), by instrumental variables (instruments: the mean and slope over the samples two away); equations \
             {hc}",
            est.steady_samples,
            est.samples,
            SteadyOptions::default().steady_sigmas
        ))
        .chain(est.notes.iter().filter(|n| n.contains("control period") || n.contains("smooth across")).cloned())
        .chain(widening)
        .collect(),
        warnings: Vec::new(),
    }
}

/// The derived quantities ([`derived`]: `k_t`, `psi_f`, the ratings) and, with a thermal
/// reference, the winding and magnet temperatures: one set per log when a parameter is
/// estimated per log, else one.
fn derived_all(est: &SteadyEstimate, options: &PmsmFitOptions) -> Vec<DerivedEstimate> {
    let kind = est.kind;
    // One set per log when a parameter is per log, else one shared set.
    let mut logs: Vec<Option<String>> = Vec::new();
    for e in est.experiment.iter().flatten() {
        if !logs.iter().flatten().any(|l| l == e) {
            logs.push(Some(e.clone()));
        }
    }
    if logs.is_empty() {
        logs.push(None);
    }
    // The quantile of the quantities of two parameters (`k_m`): the fit's.
    let tq = t_quantile_975(est.uncertainty.dof);
    let mut out = Vec::new();
    for log in logs {
        // The full vector's entry of each model parameter for this log.
        let at: Vec<usize> = kind
            .parameter_names()
            .iter()
            .filter_map(|n| {
                (0..est.names.len()).find(|&i| {
                    est.names[i] == *n && (est.experiment[i].is_none() || est.experiment[i] == log)
                })
            })
            .collect();
        if at.len() != kind.parameter_names().len() {
            continue;
        }
        let t: Vec<f64> = at.iter().map(|&i| est.theta[i]).collect();
        let s: Vec<f64> = at.iter().map(|&i| est.std_error[i]).collect();
        let corr = est.correlation[at[0]][at[at.len() - 1]];
        // The parameters' intervals (widened ones included), for the quantities of one.
        let ci: Vec<[f64; 2]> =
            at.iter().map(|&i| [est.theta[i] - est.ci95[i], est.theta[i] + est.ci95[i]]).collect();
        let with_log =
            |d: DerivedEstimate| DerivedEstimate { experiment: log.clone(), ..d.with_interval(tq) };
        out.extend(derived(kind, options.pole_pairs, &t, &s, corr, Some(&ci)).into_iter().map(with_log));
        if let Some(th) = options.thermal {
            let psi = SQRT_2_3 / f64::from(options.pole_pairs);
            let k = t.len() - 1;
            let both = [ci[0], ci[k].map(|e| psi * e)];
            out.extend(
                th.temperatures(t[0], s[0], psi * t[k], psi * s[k], Some(both)).into_iter().map(with_log),
            );
        }
    }
    out
}

/// The name the report gives the period term: the control period itself.
const PERIOD_SHOWN: &str = "h_c";

/// The control period `h_c = √h_c2` \[s\] as the report's nuisance parameter, from the
/// estimate `p` of `h_c2` \[s²\]: its interval the square roots of `h_c2`'s (clipped at
/// 0), its standard error by the delta method `se(h_c2)/(2 h_c)`, or `√se(h_c2)` when the
/// estimate is not positive (the period one standard error of `h_c2` amounts to).
fn control_period(p: ParameterEstimate) -> ParameterEstimate {
    let root = |v: f64| if v.is_nan() { v } else { v.max(0.0).sqrt() };
    let se = |s: f64| if p.value > 0.0 { s / (2.0 * p.value.sqrt()) } else { s.sqrt() };
    ParameterEstimate {
        name: PERIOD_SHOWN.into(),
        unit: "s".into(),
        value: root(p.value),
        std_error: se(p.std_error),
        std_error_white: se(p.std_error_white),
        ci95: p.ci95.map(root),
        nuisance: true,
        start: root(p.start),
        ..p
    }
}
