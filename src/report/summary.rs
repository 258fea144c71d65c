//! The fit report an engineer reads: a [`FitResult`] as a [`Document`] (parameters with
//! engineering prefixes and units on every figure, the initial states under their own
//! heading, derived quantities, conventions, goodness of fit with units, the labelled
//! correlation matrix, the solver and identifiability, remarks).
//!
//! The error index legend follows MODEL.md §5 (thesis 5.3, appendix B).

use super::eng::{UnitScale, decimals_for, format_figure};
use super::text::{Align, Document, Table};
use crate::estimate::{FitResult, ParameterEstimate};

/// The one-line legend of the "index %" column.
pub const ERROR_INDEX_LEGEND: &str = "index %: parametric error index P = 100 δθ/|θ̂| (thesis 5.3), δθ the change of \
     the parameter, the others re-optimised, that doubles the residual sum of squares; small = well excited, \
     above ~10 % poorly determined";

/// Why a free parameter's index is `—`: the estimator has no residual sum of squares of the
/// prediction-error criterion to double (the steady-state equations' regression,
/// instrumental variables).
pub const NO_ERROR_INDEX: &str = "index % —: not defined for this estimator (the index doubles the prediction-error \
     criterion's residual sum of squares, which the steady-state regression and instrumental variables do not \
     minimise)";

/// The heading of the advice, notes and warnings at the end of a report.
pub const REMARKS: &str = "remarks";

/// Most significant digits an estimate is printed with (enough to show its standard error
/// to two digits, at least five, at most this).
const MAX_SIGNIFICANT: usize = 9;

/// The cells `[estimate, std error, 95 % interval, unit]` of one estimate: all figures in
/// the unit (with prefix) chosen for the estimate, with as many digits as show the standard
/// error to two significant digits (5 to 9 significant digits). `ci: None` leaves the
/// interval empty; a fixed estimate says so; a NaN standard error (at a bound) shows `—`.
pub fn estimate_cells(
    value: f64,
    std_error: f64,
    ci: Option<[f64; 2]>,
    unit: &str,
    fixed: bool,
) -> [String; 4] {
    let s = UnitScale::for_value(value, unit);
    let v = value / s.factor;
    let se = std_error / s.factor;
    let mut d = decimals_for(v, 5);
    if se.is_finite() && se > 0.0 && !fixed {
        d = d.max(decimals_for(se, 2)).min(decimals_for(v, MAX_SIGNIFICANT));
    }
    let se_cell = if fixed {
        "fixed".to_string()
    } else if se.is_nan() {
        "—".to_string()
    } else if se.is_finite() && se > 0.0 && se < 10f64.powi(-(d as i32)) {
        // Below the last digit of the estimate: two significant digits, scientific.
        format!("{se:.1e}")
    } else {
        s.number(std_error, d)
    };
    let ci_cell = match ci {
        _ if fixed => "—".to_string(),
        Some([lo, hi]) if lo.is_nan() || hi.is_nan() => "—".to_string(),
        Some([lo, hi]) => format!("[{}, {}]", s.number(lo, d), s.number(hi, d)),
        None => String::new(),
    };
    [s.number(value, d), se_cell, ci_cell, s.symbol]
}

/// `name[experiment]`, or the name alone for a shared quantity.
pub fn label(name: &str, experiment: Option<&str>) -> String {
    experiment.map_or_else(|| name.to_string(), |e| format!("{name}[{e}]"))
}

fn parameter_row(p: &ParameterEstimate, index: bool) -> Vec<String> {
    let ci = Some(p.ci95);
    let [v, se, ci, unit] = estimate_cells(p.value, p.std_error, ci, &p.unit, p.fixed);
    let idx = match p.error_index_percent {
        _ if p.fixed || !index => "—".to_string(),
        i if i.is_finite() => format!("{i:.4}"),
        i if i.is_nan() => "—".to_string(),
        i => super::eng::format_figure(i, ""),
    };
    let mut status = Vec::new();
    if p.fixed {
        status.push("fixed");
    }
    if p.at_bound {
        status.push("at bound");
    }
    if p.nuisance {
        status.push("nuisance");
    }
    vec![label(&p.name, p.experiment.as_deref()), v, se, ci, unit, idx, status.join(", ")]
}

/// The unit of the squared residuals: `A²` when every output is in A, else empty.
fn squared_unit(units: &[String]) -> String {
    match units.first() {
        Some(u) if !u.is_empty() && units.iter().all(|x| x == u) => format!("{u}²"),
        _ => String::new(),
    }
}

impl FitResult {
    /// The report as a document; `conventions` (lines stating the model's units and
    /// scalings in words) go under their own heading after the derived quantities.
    pub fn document(&self, conventions: &[String]) -> Document {
        let mut d = Document::default();
        d.line(format!(
            "model {}; {} log(s): {}",
            self.model,
            self.experiments.len(),
            self.experiments.join(", ")
        ));
        d.heading("parameters");
        let mut t = Table::new(&[
            ("parameter", Align::Left),
            ("estimate", Align::Right),
            ("std error", Align::Right),
            ("95 % interval", Align::Right),
            ("unit", Align::Left),
            ("index %", Align::Right),
            ("", Align::Left),
        ]);
        for p in &self.parameters {
            t.push(parameter_row(p, true));
        }
        d.table(t);
        d.line(ERROR_INDEX_LEGEND);
        if self.parameters.iter().any(|p| !p.fixed && p.error_index_percent.is_nan()) {
            d.line(NO_ERROR_INDEX);
        }
        if let Some(line) = self.uncertainty_line() {
            d.line(line);
        }
        if !self.initial_states.is_empty() {
            d.heading(
                "initial state (x0: the states at each log's first sample, estimated with the parameters)",
            );
            let mut t = Table::new(&[
                ("state", Align::Left),
                ("estimate", Align::Right),
                ("std error", Align::Right),
                ("95 % interval", Align::Right),
                ("unit", Align::Left),
            ]);
            for p in &self.initial_states {
                let mut row = parameter_row(p, false);
                row.truncate(5);
                t.push(row);
            }
            d.table(t);
        }
        if !self.derived.is_empty() {
            d.heading("derived from the estimates");
            let mut t = Table::new(&[
                ("quantity", Align::Left),
                ("value", Align::Right),
                ("std error", Align::Right),
                ("95 % interval", Align::Right),
                ("unit", Align::Left),
            ]);
            // The fit's interval; for a result built without one (by hand), Student's t at
            // the covariance's degrees of freedom.
            let tq = crate::estimate::t_quantile_975(self.uncertainty.dof);
            for q in &self.derived {
                let ci = q.interval(tq);
                let [v, se, ci, unit] = estimate_cells(q.value, q.std_error, Some(ci), &q.unit, false);
                t.push(vec![label(&q.name, q.experiment.as_deref()), v, se, ci, unit]);
            }
            d.table(t);
        }
        if !conventions.is_empty() {
            d.heading("conventions");
            conventions.iter().for_each(|c| d.line(c.clone()));
        }
        self.fit_section(&mut d);
        self.correlation_section(&mut d);
        self.remarks(&mut d);
        d
    }

    /// Says how the standard errors were formed when it is not the white-noise covariance.
    fn uncertainty_line(&self) -> Option<String> {
        let u = &self.uncertainty;
        (u.method == crate::estimate::CovarianceMethod::BatchMeans).then(|| {
            let q = u.ljung_box.iter().fold(0.0f64, |a, b| a.max(*b));
            let how = match u.jackknife {
                true => "the delete-one-batch jackknife (CV3)",
                false => "the score's long-run covariance by batch means",
            };
            let interval = match u.restricted {
                true => "interval: the batch-means test inverted at the estimate restricted to each value (asymmetric \
                         where the batches carry a parameter unevenly), t",
                false => "interval t",
            };
            format!(
                "std error: residuals not white (Ljung–Box Q {q:.3e} > {:.1}): {how} over {} batches of {} samples, \
                 {interval} with {} degrees of freedom{}; the white-noise std errors are in the JSON (std_error_white)",
                u.ljung_box_critical,
                u.batches,
                u.batch_samples,
                u.dof,
                self.effective_dof_clause()
            )
        })
    }

    /// `, fewer where a few batches carry a parameter (...): r_s 13, ...` naming the free
    /// parameters whose effective degrees of freedom ([`crate::estimate::Uncertainty`]) are
    /// fewer than the batches'; empty when none is.
    fn effective_dof_clause(&self) -> String {
        let u = &self.uncertainty;
        let free = self.parameters.iter().filter(|p| !p.fixed);
        let fewer: Vec<String> = free
            .zip(&u.effective_dof)
            .filter(|(_, nu)| **nu < u.dof as f64)
            .map(|(p, nu)| {
                let log = p.experiment.as_ref().map_or_else(String::new, |e| format!("[{e}]"));
                format!("{}{log} {nu:.1}", p.name)
            })
            .collect();
        match fewer.is_empty() {
            true => String::new(),
            false => format!(
                ", fewer for a parameter that a few batches carry (Bell–McCaffrey's effective degrees of freedom, \
                 {}): {}",
                match u.restricted {
                    true => "the t of a ± t·se interval where the restricted one is unbounded",
                    false => "its interval's t",
                },
                fewer.join(", ")
            ),
        }
    }

    fn fit_section(&self, d: &mut Document) {
        let s = &self.fit;
        d.heading("goodness of fit");
        let mut t = Table::new(&[
            ("output", Align::Left),
            ("fit %", Align::Right),
            ("rms residual", Align::Right),
            ("autocorrelation beyond 95 % bound", Align::Right),
        ]);
        for (i, name) in s.outputs.iter().enumerate() {
            let unit = s.output_units.get(i).map_or("", String::as_str);
            let fit = s.fit_percent.get(i).map_or(String::new(), |f| format!("{f:.4}"));
            let rms = s.rms_residual.get(i).map_or(String::new(), |r| format_figure(*r, unit));
            let white =
                s.whiteness.get(i).map_or(String::new(), |w| format!("{:.0} %", 100.0 * w.fraction_outside));
            t.push(vec![name.clone(), fit, rms, white]);
        }
        d.table(t);
        let u2 = squared_unit(&s.output_units);
        d.line(format!(
            "loss V = {}, mse {}, FPE {} (per residual; squared output units), AIC {:.1}, BIC {:.1} \
             (dimensionless); N = {} samples per output, {} degrees of freedom",
            format_figure(s.loss, &u2),
            format_figure(s.mse, &u2),
            format_figure(s.fpe, &u2),
            s.aic,
            s.bic,
            s.samples,
            s.dof
        ));
        d.line("fit %: NRMSE fit 100 (1 − ‖y − ŷ‖/‖y − ȳ‖); whiteness over lags 1–25 (about 5 % for white residuals)");
        let predictor = s.horizon.map(|k| format!("of the {k}-step-ahead prediction the fit minimised"));
        let counted = s.counted.map(|c| {
            format!("over the {c} of {} samples the fit counts (the others weighted out)", s.samples)
        });
        if predictor.is_some() || counted.is_some() {
            let parts: Vec<String> = predictor.into_iter().chain(counted).collect();
            d.line(format!("residuals: {} (the plot and --residuals show the same)", parts.join(", ")));
        }
    }

    /// Labels of the correlation matrix: the stored ones, or the free parameters in order.
    fn correlation_labels(&self) -> Vec<String> {
        if self.correlation_names.len() == self.correlation.len() {
            return self.correlation_names.clone();
        }
        self.parameters
            .iter()
            .filter(|p| !p.fixed)
            .map(|p| label(&p.name, p.experiment.as_deref()))
            .chain((0..).map(|i| format!("#{i}")))
            .take(self.correlation.len())
            .collect()
    }

    fn correlation_section(&self, d: &mut Document) {
        if self.correlation.len() < 2 {
            return;
        }
        d.heading("correlation of the free parameters");
        let labels = self.correlation_labels();
        let mut header: Vec<(&str, Align)> = vec![("", Align::Left)];
        header.extend(labels.iter().map(|l| (l.as_str(), Align::Right)));
        let mut t = Table::new(&header);
        for (l, row) in labels.iter().zip(&self.correlation) {
            let mut cells = vec![l.clone()];
            cells.extend(row.iter().map(|c| if c.is_finite() { format!("{c:+.3}") } else { "—".into() }));
            t.push(cells);
        }
        d.table(t);
    }

    fn remarks(&self, d: &mut Document) {
        d.heading("solver");
        d.line(format!(
            "{}: {} after {} iterations ({} evaluations); fit {:.3} s{}, read {:.3} s, total {:.3} s",
            self.solver.name,
            self.solver.termination,
            self.solver.iterations,
            self.solver.evaluations,
            self.timing.fit_s,
            self.timing.solve_s.map_or_else(String::new, |s| format!(" (of which the solver {s:.3} s)")),
            self.timing.read_s,
            self.timing.total_s
        ));
        let g = &self.diagnostics;
        d.line(format!(
            "identifiability: singular values {} (relative information), condition number {:.3e}",
            g.singular_values.iter().map(|v| format!("{v:.3e}")).collect::<Vec<_>>().join(", "),
            g.condition_number
        ));
        if !(g.advice.is_empty() && self.notes.is_empty() && self.warnings.is_empty()) {
            d.heading(REMARKS);
        }
        g.advice.iter().for_each(|a| d.line(format!("advice: {a}")));
        self.notes.iter().for_each(|n| d.line(format!("note: {n}")));
        self.warnings.iter().for_each(|w| d.line(w.to_string()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_share_the_estimates_prefix() {
        let [v, se, ci, unit] = estimate_cells(4.5e-3, 2.0e-7, Some([4.4996e-3, 4.5004e-3]), "H", false);
        assert_eq!((v.as_str(), se.as_str(), unit.as_str()), ("4.50000", "0.00020", "mH"));
        assert_eq!(ci, "[4.49960, 4.50040]");
        let [v, se, ci, unit] = estimate_cells(0.9, 0.0, Some([0.9, 0.9]), "ohm", true);
        assert_eq!((v.as_str(), se.as_str(), ci.as_str(), unit.as_str()), ("900.00", "fixed", "—", "mΩ"));
        // A standard error far below nine significant digits is shown in scientific form.
        let [_, se, _, _] = estimate_cells(0.9, 1e-12, None, "ohm", false);
        assert_eq!(se, "1.0e-9");
        let [_, se, ci, _] = estimate_cells(0.9, f64::NAN, Some([f64::NAN; 2]), "ohm", false);
        assert_eq!((se.as_str(), ci.as_str()), ("—", "—"));
        let [_, se, _, _] = estimate_cells(0.9, f64::INFINITY, None, "ohm", false);
        assert_eq!(se, "∞");
    }
}
