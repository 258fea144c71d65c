//! The least-squares estimate as the same report a prediction-error fit gives
//! ([`FitResult`]): `parameters[]` with 95 % intervals, `derived`, `fit`, `diagnostics`,
//! `timing`, so that scripts read one format whatever the method.
//!
//! The "outputs" of the regression are the d and q voltage equations; intervals use
//! Student's t with the regression's degrees of freedom (thesis 5.2.1, 5.3).

use crate::estimate::diagnostics::{DiagnosticThresholds, diagnose};
use crate::estimate::metrics;
use crate::estimate::t_quantile_975;
use crate::estimate::{
    FitResult, FitStatistics, ParameterEstimate, SolverReport, Termination, Timing, Warning,
};
use crate::pmsm::linear::LinearEstimate;
use crate::pmsm::model::kind::derived;
use nalgebra::DMatrix;

impl LinearEstimate {
    /// The estimate as a [`FitResult`] for `experiments` (names) on a machine with `n_p`
    /// pole pairs; `fit_s` \[s\] is the time the estimate took.
    pub fn report(&self, experiments: &[String], n_p: u32, fit_s: f64) -> FitResult {
        let n = self.theta.len();
        let tq = t_quantile_975(self.uncertainty.dof);
        let parameters: Vec<ParameterEstimate> = (0..n)
            .map(|j| {
                let (v, se) = (self.theta[j], self.std_error[j]);
                ParameterEstimate {
                    name: self.names[j].clone(),
                    unit: self.units[j].clone(),
                    value: v,
                    std_error: se,
                    std_error_white: self.std_error_white.get(j).copied().unwrap_or(se),
                    ci95: [v - tq * se, v + tq * se],
                    error_index_percent: self.error_index_percent[j],
                    fixed: false,
                    nuisance: false,
                    at_bound: false,
                    experiment: None,
                    start: v,
                }
            })
            .collect();
        let inv = DMatrix::from_fn(n, n, |i, j| self.inverse[i][j]);
        let correlation: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|j| inv[(i, j)] / (inv[(i, i)] * inv[(j, j)]).sqrt()).collect())
            .collect();
        let info_rel = inv
            .clone()
            .try_inverse()
            .map(|a| DMatrix::from_fn(n, n, |i, j| a[(i, j)] * self.theta[i] * self.theta[j]))
            .unwrap_or_else(|| DMatrix::from_element(n, n, f64::NAN));
        let kind = self.kind;
        let diagnostics = diagnose(
            &info_rel,
            &self.names,
            &self.error_index_percent,
            &correlation,
            &DiagnosticThresholds::default(),
            &|name| kind.advice(name),
            &|a, b| kind.pair_advice(a, b),
        );
        let rows = self.rows as f64;
        let sse = self.rms_residual.iter().map(|r| r * r * rows / 2.0).sum::<f64>();
        let fit = FitStatistics {
            outputs: vec!["ud".into(), "uq".into()],
            output_units: vec!["V".into(), "V".into()],
            fit_percent: self.fit_percent.to_vec(),
            rms_residual: self.rms_residual.to_vec(),
            loss: 0.5 * self.e2,
            mse: sse / rows,
            aic: metrics::aic(sse, self.rows, n),
            bic: metrics::bic(sse, self.rows, n),
            fpe: metrics::fpe(sse, self.rows, n),
            whiteness: self.whiteness.clone(),
            samples: self.rows / 2,
            dof: self.dof,
            counted: None,
            horizon: None,
        };
        let reason = Termination::ClosedForm;
        FitResult {
            model: format!("{}_least_squares", kind.model_name()),
            experiments: experiments.to_vec(),
            derived: derived(kind, n_p, &self.theta, &self.std_error, correlation[0][n - 1], None)
                .into_iter()
                .map(|d| d.with_interval(tq))
                .collect(),
            parameters,
            initial_states: Vec::new(),
            diagnostics,
            fit,
            correlation,
            correlation_names: self.names.clone(),
            uncertainty: self.uncertainty.clone(),
            solver: SolverReport {
                name: "ls".into(),
                iterations: 0,
                termination: reason.to_string(),
                success: true,
                reason,
                evaluations: 1,
                accepted_iterations: 0,
                trace: Vec::new(),
            },
            parameter_trace: Vec::new(),
            timing: Timing { read_s: 0.0, fit_s, total_s: fit_s, solve_s: None },
            notes: vec![format!(
                "linear least squares on the voltage equations (weighting {}; prefilter {}); with noisy currents \
                 the regression is biased (errors in variables): a start, not the answer",
                self.weighting,
                self.options.prefilter.map_or("none".into(), |f| format!("{f} Hz"))
            )],
            warnings: Vec::new(),
        }
    }
}

/// Relative disagreement with the prediction-error fit beyond which a regression's bias makes
/// its report untrusted.
pub const LS_BIAS_UNTRUSTED: f64 = 0.01;

impl LinearEstimate {
    /// A warning (code `ls_biased`) when this regression and a prediction-error fit `pem` of
    /// the same logs disagree on a parameter by more than 1.96 standard errors of the
    /// difference (`√(se_ls² + se_pem²)`): the regression takes the currents' derivative as
    /// a regressor, so noise on the currents biases it (errors in variables; thesis 5.2.1),
    /// and its discretisation is approximate, while output error on the exact step is
    /// biased by neither. Untrusted (exit 3) when a disagreement also exceeds
    /// [`LS_BIAS_UNTRUSTED`] relative, a notice otherwise (the regression's usual
    /// discretisation bias on a clean log is 1e-4). `None` when they agree.
    pub fn disagreement(&self, pem: &FitResult) -> Option<Warning> {
        let mut largest = 0.0f64;
        let off: Vec<String> = self
            .names
            .iter()
            .enumerate()
            .filter_map(|(j, name)| {
                let p = pem.parameter(name)?;
                let se = (self.std_error[j].powi(2) + p.std_error.powi(2)).sqrt();
                let z = (self.theta[j] - p.value) / se;
                let rel = ((self.theta[j] - p.value) / p.value).abs();
                (z.abs() > 1.96).then(|| {
                    largest = largest.max(rel);
                    format!(
                        "{name} {:.6e} against {:.6e} ({z:+.1} σ, {:.2} %)",
                        self.theta[j],
                        p.value,
                        100.0 * rel
                    )
                })
            })
            .collect();
        (!off.is_empty()).then(|| {
            let warning = if largest > LS_BIAS_UNTRUSTED { Warning::untrusted } else { Warning::notice };
            warning(
                "ls_biased",
                format!(
                    "the regression disagrees with the prediction-error fit beyond their intervals: {}; it is \
                     biased, by noise on the currents (their derivative is a regressor: errors in variables) or by \
                     its approximate discretisation, so its intervals do not hold: use the prediction-error fit \
                     (--method pem), or --method iv with noise on the voltage",
                    off.join(", ")
                ),
            )
        })
    }
}
