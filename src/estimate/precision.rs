//! A stated accuracy as part of the trust gate: a fit whose purpose needs a parameter to a
//! given relative accuracy is untrusted (`imprecise`) when its own standard error cannot
//! promise it.
//!
//! An honest interval says how wide the estimate's uncertainty is, but a caller who exits
//! 0 only on a trusted fit (a fleet run, a temperature tracker) reads exit 0 as "good to the
//! accuracy I need". A [`PrecisionTarget`] states that need: the fit is untrusted when
//! [`PRECISION_Z`] standard errors of a parameter exceed the target's fraction of its
//! magnitude, so that an honest fit which passes has its error within the target unless
//! the error lies beyond [`PRECISION_Z`] standard errors (a 0.27 % chance for a normal
//! estimate; the same |z| ≤ 3 the project judges honesty by). A standard error estimated
//! from few degrees of freedom has Student's heavier tails: it counts times
//! `t₀.₉₇₅(dof)/1.96`, the ratio of the report's own 95 % interval to the normal one (2.3
//! at 2 degrees of freedom, 1.04 at 30), or that of the parameter's own interval where it
//! is wider (an interval widened with fewer degrees of freedom than the fit's, e.g. by the
//! spread of the fits of parts), the longer of its two sides where it is asymmetric (a
//! restricted interval, `super::restricted`: the truth may lie that far on that side).
//! Models state no target by default; the domain layers set one where their users' purpose
//! fixes it.

use super::quantile::{interval_quantile, t_quantile_975};
use super::result::{ParameterEstimate, Warning};
use serde::{Deserialize, Serialize};

/// Standard errors a parameter's stated accuracy must hold: 3, so that an honest estimate
/// that passes lies within its target with probability 0.9973 (normal errors).
pub const PRECISION_Z: f64 = 3.0;

/// The relative accuracy a fit must reach in one parameter to be trusted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrecisionTarget {
    /// The parameter's report name (each log's entry of a per-log parameter counts).
    pub parameter: String,
    /// Largest accepted [`PRECISION_Z`] standard errors as a fraction of the estimate's
    /// magnitude \[1\] (0.005 = 0.5 %); finite and positive.
    pub relative: f64,
}

/// The `imprecise` warning (untrusted) when a free parameter named in `targets` has
/// [`PRECISION_Z`] standard errors (scaled for `dof`, the degrees of freedom of the
/// intervals: module documentation) above its target's fraction of its magnitude, or a
/// standard error that is not finite; `why` says where the targets come from, `advice`
/// what would make the data more informative and how to state other targets. `None` when
/// every target holds, or there is none.
pub fn imprecise(
    parameters: &[ParameterEstimate],
    dof: usize,
    targets: &[PrecisionTarget],
    why: &str,
    advice: &str,
) -> Option<Warning> {
    let normal = t_quantile_975(usize::MAX);
    let missed: Vec<String> = parameters
        .iter()
        .filter(|p| !p.fixed)
        .filter_map(|p| {
            let target = targets.iter().find(|t| t.parameter == p.name)?;
            // The parameter's own interval's tails where they are heavier than the fit's: its
            // longer side.
            let own = interval_quantile(p.ci95, p.value, p.std_error) / normal;
            let tails = (t_quantile_975(dof) / normal).max(if own.is_finite() { own } else { 0.0 });
            let reach = PRECISION_Z * tails * p.std_error / p.value.abs();
            let label = p.experiment.as_ref().map_or_else(|| p.name.clone(), |e| format!("{}[{e}]", p.name));
            (reach.is_nan() || reach > target.relative).then(|| {
                format!("{label} known to ±{} (target {})", percent(reach), percent(target.relative))
            })
        })
        .collect();
    if missed.is_empty() {
        return None;
    }
    Some(Warning::untrusted(
        "imprecise",
        format!(
            "the estimates fall short of the stated accuracy ({why}), at {PRECISION_Z} standard errors: {}. Their \
             intervals may be honest, but they are wider than the targets: {advice}",
            missed.join(", ")
        ),
    ))
}

/// `x` (a fraction) as a percentage with two significant digits at least.
fn percent(x: f64) -> String {
    match 100.0 * x {
        p if !p.is_finite() => "∞ %".into(),
        p if p >= 10.0 => format!("{p:.0} %"),
        p if p >= 0.1 => format!("{p:.2} %"),
        p => format!("{p:.3} %"),
    }
}

#[cfg(test)]
impl ParameterEstimate {
    /// A free, non-nuisance estimate `value ± std_error` with its normal 95 % interval, for
    /// the unit tests of the checks that read reports.
    pub(crate) fn free(name: &str, value: f64, std_error: f64) -> Self {
        Self {
            name: name.into(),
            unit: String::new(),
            value,
            std_error,
            std_error_white: std_error,
            ci95: [value - 1.96 * std_error, value + 1.96 * std_error],
            error_index_percent: f64::NAN,
            fixed: false,
            nuisance: false,
            at_bound: false,
            experiment: None,
            start: value,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(name: &str, value: f64, std_error: f64) -> ParameterEstimate {
        ParameterEstimate::free(name, value, std_error)
    }

    fn target(parameter: &str, relative: f64) -> PrecisionTarget {
        PrecisionTarget { parameter: parameter.into(), relative }
    }

    #[test]
    fn a_target_is_met_by_three_standard_errors_within_it() {
        let targets = [target("a", 0.01)];
        // 3 × 0.0033 = 0.0099 < 1 % of 1: met; 3 × 0.0034 = 1.02 %: missed.
        assert!(imprecise(&[estimate("a", 1.0, 0.0033)], usize::MAX, &targets, "", "").is_none());
        let w =
            imprecise(&[estimate("a", -1.0, 0.0034)], usize::MAX, &targets, "asked", "log longer").unwrap();
        assert!(w.untrusted && w.code == "imprecise");
        assert!(
            w.message.contains("(asked)")
                && w.message.contains("a known to ±1.02 % (target 1.00 %)")
                && w.message.contains("log longer"),
            "{}",
            w.message
        );
    }

    /// An asymmetric interval counts by its longer side: `[v − 1.2 s, v + 3.0 s]` (mean half
    /// width 2.1 s) reaches 3 × 3.0/1.96 s, not 3 × 2.1/1.96 s.
    #[test]
    fn an_asymmetric_interval_counts_by_its_longer_side() {
        let targets = [target("a", 0.01)];
        let (v, s) = (1.0, 0.0025);
        let skewed =
            |lo: f64, hi: f64| ParameterEstimate { ci95: [v - lo * s, v + hi * s], ..estimate("a", v, s) };
        // Mean half width: 3 × 2.1/1.96 × 0.25 % = 0.80 %, within 1 %; longer side 1.15 %.
        let w = imprecise(&[skewed(1.2, 3.0)], usize::MAX, &targets, "", "").unwrap();
        assert!(w.message.contains("a known to ±1.15 %"), "{}", w.message);
        let w = imprecise(&[skewed(3.0, 1.2)], usize::MAX, &targets, "", "").unwrap();
        assert!(w.message.contains("a known to ±1.15 %"), "{}", w.message);
        assert!(imprecise(&[skewed(1.2, 2.5)], usize::MAX, &targets, "", "").is_none());
    }

    #[test]
    fn only_named_free_parameters_are_judged_and_a_non_finite_error_misses() {
        let targets = [target("a", 0.01)];
        let wide = estimate("b", 1.0, 10.0);
        assert!(imprecise(std::slice::from_ref(&wide), usize::MAX, &targets, "", "").is_none());
        assert!(imprecise(&[estimate("a", 1.0, 1.0)], usize::MAX, &[], "", "").is_none());
        let fixed = ParameterEstimate { fixed: true, ..estimate("a", 1.0, 1.0) };
        assert!(imprecise(&[fixed], usize::MAX, &targets, "", "").is_none());
        let w = imprecise(&[wide, estimate("a", 1.0, f64::NAN)], usize::MAX, &targets, "", "").unwrap();
        assert!(w.message.contains("a known to ±∞ %"), "{}", w.message);
        let per_log = ParameterEstimate { experiment: Some("log2".into()), ..estimate("a", 2.0, 1.0) };
        assert!(
            imprecise(&[per_log], usize::MAX, &targets, "", "")
                .unwrap()
                .message
                .contains("a[log2] known to ±150 %")
        );
    }
}
