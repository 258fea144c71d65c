//! The statistics of a fit at its estimate, assembled once into a [`FitResult`]: sandwich
//! covariance, intervals, error index, correlation, diagnostics, fit statistics and the
//! model's derived quantities (MODEL.md §5; Ljung 9.3, 16.4; thesis 5.3).

use super::covariance::{Covariance, Inverse, Meat};
use super::diagnostics::{DiagnosticThresholds, diagnose};
use super::gate;
use super::problem::{FreeKind, MIN_BATCHES, PemProblem, Slot};
use super::quantile::t_quantile_975;
use super::{FitResult, FitStatistics, ParameterEstimate, SolverReport, Timing, Uncertainty};
use crate::error::Result;
use crate::estimate::metrics;
use crate::model::DerivedEstimate;
use crate::model::GreyBoxModel;
use nalgebra::{DMatrix, DVector};

/// Relative distance (to the larger of the estimate and its start) within which a free
/// parameter counts as at its bound.
pub const AT_BOUND: f64 = 1e-6;

/// A static model's self-consistency check at the estimate θ (model order): `None` when it
/// cannot run, `Some(None)` when the fits of consecutive parts agree, `Some(Some(why))`
/// when they do not.
pub(crate) type PartsCheck<'a> = dyn Fn(&[f64]) -> Option<Option<String>> + 'a;

/// Computes the statistics at p̂ and fills a [`FitResult`]; `correction`: the term the
/// criterion was compensated by, if any.
pub(crate) fn assemble<M: GreyBoxModel>(
    problem: &PemProblem<'_, M>,
    p: &DVector<f64>,
    start: &[f64],
    mut solver: SolverReport,
    thresholds: &DiagnosticThresholds,
    parts: Option<&PartsCheck<'_>>,
    correction: Option<&dyn crate::estimate::CriterionCorrection>,
) -> Result<FitResult> {
    let model = problem.model();
    let params = model.parameters();
    let (ny, np) = (model.n_outputs(), problem.n_free());
    let sums = problem.sums(p)?;
    let n = sums.count;
    let n_res = n * ny;
    let dof = n_res.saturating_sub(np);
    // The residual figures are over the samples the criterion counts: a sample weighted out
    // (a dead-time mask) is not fitted and would report the structure it was dropped for.
    let counted =
        (sums.n_live.iter().any(|&c| c < n)).then(|| sums.n_live.iter().copied().max().unwrap_or(0));
    let (sse, n_fig): (&[f64], Vec<usize>) = match counted {
        Some(_) => (&sums.sse_live, sums.n_live.clone()),
        None => (&sums.sse, vec![n; ny]),
    };
    let n_res_fig: usize = n_fig.iter().sum();
    let sse_total: f64 = sse.iter().sum();
    // Inverses for the reported covariance and error index (the one explicit inverse,
    // STYLE.md rule 7): bread⁻¹ meat bread⁻¹ (sandwich) and (JᵀWJ)⁻¹.
    // Parameters the data do not see at all (a zero column, e.g. an initial state whose
    // transient is weighted out) are left out of the inversion and get an infinite error.
    let (info_inv, bread_inv) = (Inverse::of(&sums.jtj), Inverse::of(&sums.bread));
    // Kept by arrowhead blocks, where the elimination failed: a column of one experiment's
    // block (a per-experiment parameter or initial state) or of the shared system.
    let singular_at = info_inv.as_ref().err().or(bread_inv.as_ref().err()).copied().flatten();
    let (info_inv, bread_inv) = (info_inv.ok(), bread_inv.ok());
    let dtheta: Vec<f64> =
        problem.free().iter().enumerate().map(|(g, f)| f.transform.dtheta_dp(p[g])).collect();
    let sandwich = |meat: Meat<'_>| Covariance::sandwich(&bread_inv, meat, &dtheta);
    // Residual whiteness from the lag sums of the raw output errors of every experiment
    // (streamed by the statistics pass), lags kept within each experiment; residuals that
    // fail it take the score's batch-means covariance (see `problem::batches`).
    let whiteness: Vec<metrics::Whiteness> =
        sums.lag_sums.iter().map(|segments| metrics::whiteness_of(segments)).collect();
    let offered = sums.batch_means.as_ref().filter(|_| dof > 0);
    let uncertainty = Uncertainty::choose(&whiteness, n, dof, offered);
    let batch_means = uncertainty.taken(offered);
    let cov_white = sandwich(Meat::Gram(&sums.meat));
    let cov_batches = batch_means.map(|b| sandwich(Meat::Batches(b)));
    // A compensated criterion's estimate also depends on the noise through what the
    // compensation and the model's own choices read off the data (its noise level, which
    // samples count), which the score's long-run covariance does not see: each parameter
    // keeps the larger of the two standard errors, with the batch means' correlations.
    let cov_batches = match (cov_batches, &cov_white, correction) {
        (Some(Some(Covariance::Dense(b))), Some(Covariance::Dense(w)), Some(_)) => {
            Some(Some(Covariance::Dense(crate::estimate::correction::larger_errors(&b, w))))
        }
        (other, _, _) => other,
    };
    let cov_theta = cov_batches.as_ref().unwrap_or(&cov_white);
    let tq = t_quantile_975(uncertainty.dof);
    let standard_errors = |cov: &Option<Covariance>| -> Vec<f64> {
        (0..np)
            .map(|g| {
                let unseen = sums.bread[(g, g)].is_nan() || sums.bread[(g, g)] <= 0.0;
                match cov {
                    Some(c) if !unseen && dof > 0 => c.entry(g, g).max(0.0).sqrt(),
                    _ => f64::INFINITY,
                }
            })
            .collect()
    };
    // Standard error of every free entry; without degrees of freedom there is no noise
    // estimate, hence no standard error. An initial state is seen by the first samples
    // only, inside one batch, whose sum the estimate sets to zero: batch means cannot tell
    // its variance, so it keeps the white one; so does a per-experiment parameter of an
    // experiment with fewer than MIN_BATCHES batches of its own.
    let se_white = standard_errors(&cov_white);
    let few = |e: Option<usize>| {
        batch_means
            .is_some_and(|b| e.is_some_and(|e| b.per_experiment.get(e).is_none_or(|&n| n < MIN_BATCHES)))
    };
    let se_free: Vec<f64> = standard_errors(cov_theta)
        .into_iter()
        .zip(&se_white)
        .zip(problem.free())
        .map(|((se, white), f)| match f.kind {
            FreeKind::InitialState(_) => *white,
            FreeKind::Parameter(_) if few(f.experiment) => *white,
            FreeKind::Parameter(_) => se,
        })
        .collect();
    let white_only =
        problem.free().iter().any(|f| matches!(f.kind, FreeKind::Parameter(_)) && few(f.experiment));
    let names = problem.terms().iter().map(|t| t.prep.name.clone()).collect::<Vec<_>>();
    let states = model.states();
    let estimate = |g: usize, name: String, unit: String, start: f64| {
        let f = &problem.free()[g];
        let value = f.transform.to_theta(p[g]);
        let se = se_free[g];
        let idx = info_inv.as_ref().map_or(f64::INFINITY, |ai| {
            100.0 * (sums.e2_weighted * ai.entry(g, g)).max(0.0).sqrt() * dtheta[g].abs() / value.abs()
        });
        // At a bound the quadratic model of the loss does not hold (the gradient is not zero
        // there): no standard error, no interval, and the flag says why.
        let at_bound = match f.kind {
            FreeKind::Parameter(j) => {
                let scale = value.abs().max(start.abs()).max(f64::MIN_POSITIVE);
                let near = |b: f64| b.is_finite() && (value - b).abs() <= AT_BOUND * scale;
                near(params[j].lower) || near(params[j].upper)
            }
            FreeKind::InitialState(_) => false,
        };
        let se = if at_bound { f64::NAN } else { se };
        ParameterEstimate {
            name,
            unit,
            value,
            std_error: se,
            std_error_white: if at_bound { f64::NAN } else { se_white[g] },
            ci95: [value - tq * se, value + tq * se],
            error_index_percent: idx,
            fixed: false,
            nuisance: false,
            at_bound,
            experiment: f.experiment.map(|e| names[e].clone()),
            start,
        }
    };
    let mut parameters = Vec::new();
    // Free entries of `parameters`, in order, are the free indices in `order`.
    let mut order = Vec::new();
    for (j, prm) in params.iter().enumerate() {
        let copies: Vec<usize> =
            (0..np).filter(|&g| problem.free()[g].kind == FreeKind::Parameter(j)).collect();
        if copies.is_empty() {
            parameters.push(ParameterEstimate {
                name: prm.name.clone(),
                unit: prm.unit.clone(),
                value: start[j],
                std_error: 0.0,
                std_error_white: 0.0,
                ci95: [start[j], start[j]],
                error_index_percent: 0.0,
                fixed: true,
                nuisance: prm.nuisance,
                at_bound: false,
                experiment: None,
                start: start[j],
            });
        }
        for g in copies {
            let e = estimate(g, prm.name.clone(), prm.unit.clone(), start[j]);
            parameters.push(ParameterEstimate { nuisance: prm.nuisance, ..e });
            order.push(g);
        }
    }
    let mut initial_states = Vec::new();
    for (g, f) in problem.free().iter().enumerate() {
        if let (FreeKind::InitialState(i), Some(e)) = (f.kind, f.experiment) {
            let x0 = problem.terms()[e].prep.x0[i];
            let s = &states[i];
            initial_states.push(estimate(g, format!("x0_{}", s.name), s.unit.clone(), x0));
        }
    }
    // Kept by arrowhead blocks, the correlation and the identifiability diagnostics are
    // of the shared parameters (a per-experiment parameter's correlations would make the
    // report grow with the square of the experiments).
    let structured = problem.layout().is_some();
    let order_all = order.clone();
    if structured {
        order.retain(|&g| problem.free()[g].experiment.is_none());
    }
    let correlation = match cov_theta {
        Some(c) => order
            .iter()
            .map(|&a| order.iter().map(|&b| c.entry(a, b) / (c.entry(a, a) * c.entry(b, b)).sqrt()).collect())
            .collect(),
        None => vec![vec![f64::NAN; order.len()]; order.len()],
    };
    let name_of = |g: usize| {
        let f = &problem.free()[g];
        let FreeKind::Parameter(j) = f.kind else { unreachable!("order holds model parameters only") };
        match f.experiment {
            Some(e) => format!("{}[{}]", params[j].name, names[e]),
            None => params[j].name.clone(),
        }
    };
    let diag_names: Vec<String> = order.iter().map(|&g| name_of(g)).collect();
    let rel = |g: usize| problem.free()[g].transform.to_theta(p[g]) / dtheta[g];
    let info_rel = DMatrix::from_fn(order.len(), order.len(), |a, b| {
        let (ga, gb) = (order[a], order[b]);
        sums.jtj[(ga, gb)] * rel(ga) * rel(gb)
    });
    // The free parameters' error indices are in the order of `order_all`; the diagnostics
    // take those of `order`.
    let free_index: Vec<f64> = parameters
        .iter()
        .filter(|q| !q.fixed)
        .zip(&order_all)
        .filter(|(_, g)| !structured || order.contains(g))
        .map(|(q, _)| q.error_index_percent)
        .collect();
    let diagnostics = diagnose(
        &info_rel,
        &diag_names,
        &free_index,
        &correlation,
        thresholds,
        &|n| model.advice(n),
        &|a, b| model.pair_advice(a, b),
    );
    let fit = FitStatistics {
        outputs: model.outputs().into_iter().map(|o| o.name).collect(),
        output_units: model.outputs().into_iter().map(|o| o.unit).collect(),
        fit_percent: sse
            .iter()
            .zip(&sums.sst)
            .zip(&n_fig)
            .map(|((e, t), &c)| metrics::fit_percent(if c == n { *e } else { e * n as f64 / c as f64 }, *t))
            .collect(),
        rms_residual: sse.iter().zip(&n_fig).map(|(e, &c)| (e / c as f64).sqrt()).collect(),
        loss: sums.cost,
        mse: sse_total / n_res_fig as f64,
        fpe: metrics::fpe(sse_total, n_res_fig, np),
        aic: metrics::aic(sse_total, n_res_fig, np),
        bic: metrics::bic(sse_total, n_res_fig, np),
        whiteness,
        samples: n,
        dof,
        counted,
        horizon: problem.horizon(),
    };
    let mut notes = Vec::new();
    let mut diagnostics = diagnostics;
    for (name, f) in fit.outputs.iter().zip(&fit.fit_percent) {
        if *f < gate::POOR_FIT_PERCENT {
            let what = model.poor_fit_advice().map(|a| format!(": {a}")).unwrap_or_default();
            diagnostics.advice.push(format!("poor fit of {name} ({f:.1} %){what}"));
        }
    }
    if white_only {
        notes.push(format!(
            "the residuals are not white, but a per-log parameter's log is too short for {MIN_BATCHES} batches of its \
             own: its standard error is the white one, which coloured residuals make too small"
        ));
    }
    if dof == 0 {
        notes.push(format!(
            "no degrees of freedom ({n_res} residuals, {np} free parameters): the residuals carry no noise \
             estimate, so standard errors and intervals are unknown (∞); add samples"
        ));
    }
    if info_inv.is_none() || bread_inv.is_none() {
        let at = singular_at.map(|g| {
            let f = &problem.free()[g];
            let name = match f.kind {
                FreeKind::Parameter(j) => params[j].name.clone(),
                FreeKind::InitialState(i) => format!("x0_{}", states[i].name),
            };
            match f.experiment {
                Some(e) => format!(" (the block of experiment `{}` is singular at `{name}`)", names[e]),
                None => format!(" (the shared parameters' reduced system is singular, from `{name}` on)"),
            }
        });
        notes.push(format!(
            "information matrix JᵀWJ is singular: some parameters are not identifiable from these data{}",
            at.unwrap_or_default()
        ));
    }
    let derived = derived(problem, p, cov_theta.as_ref(), &se_free, &names)
        .into_iter()
        .map(|d| d.with_interval(tq))
        .collect();
    let parameter_trace = std::mem::take(&mut solver.trace)
        .iter()
        .map(|q| order_all.iter().map(|&g| problem.free()[g].transform.to_theta(q[g])).collect())
        .collect();
    let all_names: Vec<String> =
        if structured { order_all.iter().map(|&g| name_of(g)).collect() } else { diag_names.clone() };
    // A compensated criterion is stationary where the score equals the correction's
    // gradient ([`crate::estimate::correction`]).
    let score = match correction {
        Some(c) => {
            &sums.score + crate::estimate::correction::Compensated { problem, correction: c }.correction(p)?.1
        }
        None => sums.score.clone(),
    };
    let evidence = gate::Evidence {
        remaining: gate::remaining(&bread_inv, &score, &order_all, &dtheta, &se_free, &all_names, |g| {
            problem.free()[g].transform.to_theta(p[g])
        }),
        condition: gate::scaled_condition(&sums.jtj, &order, &diag_names),
        implausible: gate::implausible(problem, p),
        undetermined: gate::undetermined(problem, p, &parameters, &order_all),
        white: fit.whiteness.iter().map(|w| w.is_white(n)).collect(),
        poor_fit_advice: model.poor_fit_advice(),
        // A static model's poor fit: do fits of consecutive parts agree? (Structure left
        // shows there whatever the samples' order.)
        parts: parts
            .filter(|_| model.n_states() == 0 && fit.fit_percent.iter().any(|f| *f < gate::POOR_FIT_PERCENT))
            .and_then(|check| check(&problem.theta(0, p))),
    };
    let coloured = super::colour::unbatched(&uncertainty, &fit, &parameters, model.n_states() > 0);
    let warnings =
        gate::warnings(&solver, &parameters, &fit, &evidence).into_iter().chain(coloured).collect();
    Ok(FitResult {
        model: model.name().to_string(),
        experiments: names,
        parameters,
        initial_states,
        derived,
        diagnostics,
        fit,
        correlation,
        correlation_names: diag_names,
        uncertainty,
        solver,
        parameter_trace,
        timing: Timing::default(),
        notes,
        warnings,
    })
}

/// The model's derived quantities per experiment's θ and θ-covariance (n_θ × n_θ: the
/// sandwich covariance of the free entries, 0 for fixed ones, the reported standard error
/// squared on the diagonal), once when every experiment gives the same.
fn derived<M: GreyBoxModel>(
    problem: &PemProblem<'_, M>,
    p: &DVector<f64>,
    cov: Option<&Covariance>,
    se: &[f64],
    names: &[String],
) -> Vec<DerivedEstimate> {
    let model = problem.model();
    let per_experiment: Vec<Vec<DerivedEstimate>> = (0..names.len())
        .map(|e| {
            let theta = problem.theta(e, p);
            let slots = &problem.terms()[e].slots;
            let free = |j: usize| match slots[j] {
                Slot::Free(g) => Some(g),
                Slot::Fixed(_) => None,
            };
            let c: Vec<Vec<f64>> = (0..theta.len())
                .map(|i| {
                    (0..theta.len())
                        .map(|j| match (free(i), free(j)) {
                            (Some(g), Some(_)) if i == j => se[g] * se[g],
                            (Some(g), Some(h)) if se[g].is_finite() && se[h].is_finite() => {
                                cov.map_or(f64::NAN, |c| c.entry(g, h))
                            }
                            (Some(_), Some(_)) => f64::NAN,
                            _ => 0.0,
                        })
                        .collect()
                })
                .collect();
            model.derived(&theta, &c)
        })
        .collect();
    match per_experiment.split_first() {
        Some((first, rest)) if rest.iter().all(|d| d == first) => first.clone(),
        _ => per_experiment
            .into_iter()
            .zip(names)
            .flat_map(|(d, e)| d.into_iter().map(|q| DerivedEstimate { experiment: Some(e.clone()), ..q }))
            .collect(),
    }
}
