//! What the steady-state fit of slow telemetry must reach to be trusted besides the trust
//! gate (issue 43): enough residual degrees of freedom for its intervals to mean anything
//! ([`STEADY_MIN_DOF`], warning `few_samples`), and the accuracy telemetry is fitted for
//! ([`STEADY_PRECISION`], or the options' own; warning `imprecise`,
//! [`crate::estimate::imprecise`]).

use crate::estimate::{FitResult, PrecisionTarget, Warning, imprecise};
use crate::pmsm::options::PmsmFitOptions;

/// The accuracy a steady-state fit must reach to be trusted when the options state none
/// ([`PmsmFitOptions::precision`], [`crate::estimate::imprecise`]): `r_s` to 0.5 % and `k_e`
/// to 0.05 % (three standard errors). Slow telemetry is fitted to follow the winding and
/// magnet temperatures: 0.5 % of R_s is 1.3 K of copper ([`crate::pmsm::ALPHA_COPPER`]),
/// 0.05 % of K_e 0.45 K of NdFeB ([`crate::pmsm::BETA_NDFEB`]). Sparse or short telemetry
/// gives honest intervals wider than that (a drive cycle's every 160th row: R_s to ±8 %),
/// which a fleet run that keeps exit 0 would read as a temperature.
pub const STEADY_PRECISION: [(&str, f64); 2] = [("r_s", 0.005), ("k_e", 0.0005)];

/// Fewest residual degrees of freedom (two equations a smooth sample, less the unknowns)
/// of a trusted steady-state fit: 8. Its noise estimate rests on them; with fewer the
/// standard errors are not to be relied on even as an order of magnitude: 2 smooth samples
/// (1 degree of freedom) of every 7000th row of a shared log put K_e +0.70 % off at
/// z 345. Eight is also the fewest batches the batch-means covariance accepts.
pub const STEADY_MIN_DOF: usize = 8;

/// What makes slow telemetry more informative, the `imprecise` warning's advice.
const PRECISION_ADVICE: &str = "the steady samples do not carry that much information; log faster, longer, or with \
                                more distinct speeds and currents; --precision sets the targets (off: none)";

/// The untrusted warnings of the steady-state fit `report` with `options`: `few_samples`
/// below [`STEADY_MIN_DOF`] residual degrees of freedom, `imprecise` where the stated
/// accuracy (the options', else [`STEADY_PRECISION`]) is not reached.
pub(super) fn warnings(report: &FitResult, options: &PmsmFitOptions) -> Vec<Warning> {
    let few = (report.fit.dof < STEADY_MIN_DOF).then(|| {
        Warning::untrusted(
            "few_samples",
            format!(
                "the steady-state equations rest on {} smooth samples (two equations each) for {} unknowns: {} \
                 degrees of freedom, fewer than {STEADY_MIN_DOF}, so the noise's estimate and the intervals are not \
                 to be relied on; a longer log, or one at a faster rate",
                report.fit.samples,
                report.parameters.len(),
                report.fit.dof
            ),
        )
    });
    let (targets, source) = match &options.precision {
        Some(targets) => (targets.clone(), "--precision"),
        None => (
            STEADY_PRECISION
                .iter()
                .map(|&(p, relative)| PrecisionTarget { parameter: p.into(), relative })
                .collect(),
            "the steady-state fit's default for telemetry: 1.3 K of winding, 0.45 K of magnet temperature",
        ),
    };
    let precise = imprecise(&report.parameters, report.uncertainty.dof, &targets, source, PRECISION_ADVICE);
    few.into_iter().chain(precise).collect()
}
