//! Whether fits of parts of the data agree within their intervals: Cochran's Q test of
//! homogeneity per parameter (Cochran, *Biometrics* 10 (1954) 101–129), the test of
//! meta-analysis applied to consecutive segments of one record.
//!
//! A model that is right up to white or coloured noise gives the same parameters, within
//! their standard errors, on every long enough part of the data. A model error that
//! depends on the operating point (an unmodelled nonlinearity, switching ripple, a drifting
//! parameter) biases each part differently, and the parts disagree. The whole record's
//! interval cannot show that bias: its covariance describes the noise around the
//! estimate, not the distance of the estimate from the truth.

use crate::estimate::FitResult;
use serde::{Deserialize, Serialize};

/// Cochran's Q test of one parameter over the segments' fits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Homogeneity {
    /// The parameter's name.
    pub name: String,
    /// Inverse-variance pooled estimate `θ̄ = Σ w_k θ_k / Σ w_k`, `w_k = 1/σ_k²` \[unit\].
    pub pooled: f64,
    /// The segments' estimates `θ_k` \[unit\], in segment order.
    pub estimates: Vec<f64>,
    /// Their standard errors `σ_k` \[unit\], with the floor of [`homogeneity`].
    pub std_errors: Vec<f64>,
    /// `Q = Σ w_k (θ_k − θ̄)²` (χ² with K − 1 degrees of freedom when the segments agree).
    pub q: f64,
    /// Degrees of freedom K − 1.
    pub dof: usize,
    /// `P(χ²_{K−1} ≥ Q)`.
    pub p_value: f64,
    /// Largest `|θ_k − θ̄| / |θ̄|` (relative; ∞ for θ̄ = 0).
    pub relative_spread: f64,
}

/// Cochran's Q of every free shared parameter the fits `segments` all estimate with a
/// finite, positive standard error, in the order of the first fit's parameters. Each
/// standard error is taken at least `floor` (relative) of the parameter's size, in
/// quadrature (`σ_k² + (floor · mean |θ|)²`): segments that agree to the accuracy of an exact
/// fit agree, whatever their rounding-sized intervals say. Empty for fewer than two
/// segments.
///
/// Source: Cochran, *Biometrics* 10 (1954) 101–129; the same statistic as the Wald test of
/// equal parameters across independent samples (Chow, *Econometrica* 28 (1960) 591–605).
pub fn homogeneity(segments: &[FitResult], floor: f64) -> Vec<Homogeneity> {
    let Some(first) = segments.first().filter(|_| segments.len() > 1) else {
        return Vec::new();
    };
    first
        .parameters
        .iter()
        .filter(|p| !p.fixed && p.experiment.is_none())
        .filter_map(|p| {
            let pairs: Option<Vec<(f64, f64)>> =
                segments.iter().map(|s| usable(s.parameter(&p.name)?)).collect();
            let (estimates, std_errors): (Vec<f64>, Vec<f64>) = pairs?.into_iter().unzip();
            Some(floored_test(&p.name, estimates, &std_errors, floor))
        })
        .collect()
}

/// As [`homogeneity`], for parts that need not all estimate every parameter (a standstill
/// test whose parts each excite one axis): each free shared parameter, in the order the
/// fits first name it, tested over the fits that estimate it with a finite, positive
/// standard error, when there are at least two of them.
pub fn homogeneity_where_estimated(segments: &[FitResult], floor: f64) -> Vec<Homogeneity> {
    let mut names: Vec<&str> = Vec::new();
    for p in segments.iter().flat_map(|s| &s.parameters) {
        if !p.fixed && p.experiment.is_none() && !names.contains(&p.name.as_str()) {
            names.push(&p.name);
        }
    }
    names
        .into_iter()
        .filter_map(|name| {
            let (estimates, std_errors): (Vec<f64>, Vec<f64>) =
                segments.iter().filter_map(|s| usable(s.parameter(name).filter(|q| !q.fixed)?)).unzip();
            (estimates.len() >= 2).then(|| floored_test(name, estimates, &std_errors, floor))
        })
        .collect()
}

/// The parameters on which the fits of consecutive parts `fits` disagree beyond their
/// intervals: Cochran's Q of each (standard errors taken at least `floor` relative, the
/// accuracy of an exact fit) below `family_level` divided by the number of parameters
/// tested (Bonferroni), with a spread above `floor`; each with the parts' estimates and the
/// test, joined by `; `. `None` when they agree (or fewer than two fits).
pub fn disagreement(fits: &[FitResult], floor: f64, family_level: f64) -> Option<String> {
    disagreement_of(&homogeneity(fits, floor), floor, family_level)
}

/// [`disagreement`]'s verdict on given `tests` ([`homogeneity`] or
/// [`homogeneity_where_estimated`]): those whose Q is below `family_level` divided by their
/// number, with a relative spread above `floor`, each with the parts' estimates and the
/// test, joined by `; `. `None` when none is.
pub fn disagreement_of(tests: &[Homogeneity], floor: f64, family_level: f64) -> Option<String> {
    let failed = disagreeing(tests, floor, family_level);
    if failed.is_empty() {
        return None;
    }
    let detail: Vec<String> = failed
        .iter()
        .map(|h| {
            let values: Vec<String> =
                h.estimates.iter().zip(&h.std_errors).map(|(v, s)| format!("{v:.6e} ± {s:.1e}")).collect();
            format!(
                "{} {} ({:.2e} apart relative; Q {:.1} on {} degrees of freedom, p {:.1e})",
                h.name,
                values.join(", "),
                h.relative_spread,
                h.q,
                h.dof,
                h.p_value
            )
        })
        .collect();
    Some(detail.join("; "))
}

/// The tests among `tests` whose Q is below `family_level` divided by their number
/// (Bonferroni) with a relative spread above `floor`, in their order: the parameters
/// [`disagreement_of`] names.
pub fn disagreeing(tests: &[Homogeneity], floor: f64, family_level: f64) -> Vec<&Homogeneity> {
    let level = family_level / tests.len().max(1) as f64;
    tests.iter().filter(|h| h.p_value < level && h.relative_spread > floor).collect()
}

/// A standard error `std_error` widened by the spread of the parts' fits `h`:
/// `(τ, √(σ² + τ²), t_0.975(K − 1) · √(σ² + τ²))`, `τ²` the between-part variance
/// ([`between_variance`]) and the last the 95 % half width with Student's t over the K
/// parts τ is estimated from (the form of a random-effects prediction interval: Higgins,
/// Thompson & Spiegelhalter, *J. R. Stat. Soc. A* 172, 2009). Units of `std_error`.
pub fn widened_by_parts(std_error: f64, h: &Homogeneity) -> (f64, f64, f64) {
    let tau = between_variance(h).sqrt();
    let widened = std_error.hypot(tau);
    (tau, widened, crate::estimate::t_quantile_975(h.dof) * widened)
}

/// The between-part variance `τ²` of a parameter whose parts disagree \[unit²\]: the
/// Paule–Mandel estimator (Paule & Mandel, *J. Res. Natl. Bur. Stand.* 87 (1982) 377–385),
/// the `τ²` at which the generalised Q, `Σ (θ_k − μ)² / (σ_k² + τ²)` with `μ` the mean
/// weighted by `1/(σ_k² + τ²)`, equals its expectation `K − 1`; 0 when the parts agree
/// within their errors (Q ≤ K − 1 at `τ² = 0`). Recommended over DerSimonian & Laird's
/// moment estimator where the parts' errors differ by orders of magnitude (Veroniki et
/// al., *Research Synthesis Methods* 7 (2016) 55–79): parts that the model happens to fit
/// closely carry almost all of DerSimonian–Laird's weight, whose `τ` then falls far below
/// the parts' spread (20 times on a measured case). Solved by bisection on `τ²` (the
/// generalised Q falls monotonically in it) to 1e-12 of the bracket.
pub fn between_variance(h: &Homogeneity) -> f64 {
    let excess = |tau2: f64| {
        let w: Vec<f64> = h.std_errors.iter().map(|s| 1.0 / (s * s + tau2)).collect();
        pooled_q(&h.estimates, &w).1 - h.dof as f64
    };
    let at_zero = excess(0.0);
    if h.dof == 0 || at_zero.is_nan() || at_zero <= 0.0 {
        return 0.0;
    }
    // At τ² = Σ (θ_k − θ̄)² (unweighted, times K) every weight is below 1/τ², so the
    // generalised Q is below K − 1: the root lies in the bracket.
    let mean = h.estimates.iter().sum::<f64>() / h.estimates.len() as f64;
    let (mut lo, mut hi) =
        (0.0, h.estimates.iter().map(|t| (t - mean).powi(2)).sum::<f64>() * h.estimates.len() as f64);
    if !(hi > 0.0 && hi.is_finite()) {
        return 0.0;
    }
    let width = hi;
    while hi - lo > 1e-12 * width {
        let mid = 0.5 * (lo + hi);
        if excess(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Parts a static model's data are cut into by [`static_parts`].
pub const PARTS: usize = 4;

/// Accuracy of an exact fit (relative) for [`static_parts`]: standard errors are taken at
/// least this large, and smaller spreads agree.
pub const PARTS_FLOOR: f64 = 1e-5;

/// Family-wise level of [`static_parts`]'s test (Bonferroni over the parameters).
pub const PARTS_LEVEL: f64 = 1e-3;

/// A fit of some experiments from a start (model order): the refit of [`static_parts`].
pub type Refit<'a> = dyn Fn(&[crate::data::Experiment], &[f64]) -> crate::Result<FitResult> + 'a;

/// A static model's self-consistency at its estimate `theta`: `experiments` cut into
/// [`PARTS`] consecutive parts ([`consecutive_parts`]), each part fitted by
/// `refit(part, theta)`, and [`disagreement`] of the fits. `None` when a part is too short
/// (fewer samples than twice the parameters) or fewer than two parts can be fitted;
/// `Some(None)` when they agree; `Some(Some(why))` when not.
///
/// Why: a wrong model leaves structure that a whiteness test along the data's order finds
/// only when the regressors vary along that order; fits of parts name the parameters the
/// structure moves (NIST StRD's Nelson: b3 from −0.009 to −0.065 over its four aging-time
/// quarters, its replicates' lack-of-fit F 11.0 on (29, 96)).
pub fn static_parts(
    experiments: &[crate::data::Experiment],
    theta: &[f64],
    refit: &Refit<'_>,
) -> Option<Option<String>> {
    let parts = consecutive_parts(experiments, PARTS, 2 * theta.len().max(1)).ok()?;
    let fits: Vec<FitResult> = parts.iter().filter_map(|part| refit(part, theta).ok()).collect();
    (fits.len() >= 2).then(|| disagreement(&fits, PARTS_FLOOR, PARTS_LEVEL))
}

/// `experiments` cut into `parts` consecutive parts of at least `min` samples each: part k
/// holds the k-th part of every experiment, named `NAME@k`.
///
/// # Errors
/// [`crate::Error::TooShort`] when a part would hold fewer than `min` samples; those of
/// [`crate::data::Experiment::slice`].
pub fn consecutive_parts(
    experiments: &[crate::data::Experiment],
    parts: usize,
    min: usize,
) -> crate::Result<Vec<Vec<crate::data::Experiment>>> {
    let parts = parts.max(1);
    if let Some(short) = experiments.iter().find(|e| e.len() / parts < min) {
        return Err(crate::Error::TooShort {
            name: short.name().to_string(),
            len: short.len(),
            min: parts * min,
        });
    }
    (0..parts)
        .map(|k| {
            experiments
                .iter()
                .map(|e| {
                    let n = e.len();
                    Ok(e.slice(k * n / parts..(k + 1) * n / parts)?.renamed(format!(
                        "{}@{}",
                        e.name(),
                        k + 1
                    )))
                })
                .collect()
        })
        .collect()
}

/// A parameter's `(estimate, standard error)` when both are finite and the standard error
/// positive (a part that cannot tell the parameter is left out of its test).
fn usable(q: &crate::estimate::ParameterEstimate) -> Option<(f64, f64)> {
    (q.std_error.is_finite() && q.std_error > 0.0 && q.value.is_finite()).then_some((q.value, q.std_error))
}

/// [`test`] with each standard error taken at least `floor` (relative) of the estimates'
/// mean size, in quadrature ([`homogeneity`]).
fn floored_test(name: &str, estimates: Vec<f64>, std_errors: &[f64], floor: f64) -> Homogeneity {
    let size = floor * estimates.iter().map(|t| t.abs()).sum::<f64>() / estimates.len() as f64;
    let std_errors = std_errors.iter().map(|s| s.hypot(size)).collect();
    test(name, estimates, std_errors)
}

/// The mean of `estimates` weighted by `w` and `Σ w_k (θ_k − θ̄)²` about it (Cochran's Q
/// for `w_k = 1/σ_k²`; the generalised Q of [`between_variance`] for `1/(σ_k² + τ²)`).
fn pooled_q(estimates: &[f64], w: &[f64]) -> (f64, f64) {
    let pooled = w.iter().zip(estimates).map(|(w, t)| w * t).sum::<f64>() / w.iter().sum::<f64>();
    (pooled, w.iter().zip(estimates).map(|(w, t)| w * (t - pooled).powi(2)).sum())
}

/// Cochran's Q of one parameter's estimates and standard errors.
fn test(name: &str, estimates: Vec<f64>, std_errors: Vec<f64>) -> Homogeneity {
    let w: Vec<f64> = std_errors.iter().map(|s| 1.0 / (s * s)).collect();
    let (pooled, q) = pooled_q(&estimates, &w);
    let dof = estimates.len() - 1;
    let spread = estimates.iter().map(|t| (t - pooled).abs()).fold(0.0, f64::max);
    Homogeneity {
        name: name.to_string(),
        pooled,
        relative_spread: if pooled == 0.0 { f64::INFINITY } else { spread / pooled.abs() },
        estimates,
        std_errors,
        q,
        dof,
        p_value: chi_square_sf(q, dof),
    }
}

/// `P(χ²_k ≥ x)`, the χ² survival function for `k ≥ 1` degrees of freedom, in closed form
/// (Abramowitz & Stegun 26.4.4–26.4.5): a finite sum for even `k`, `erfc` plus one for odd
/// `k`. 1 for `x ≤ 0`; NaN for `k = 0` or a NaN `x`.
pub fn chi_square_sf(x: f64, k: usize) -> f64 {
    if k == 0 || x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    let half = x / 2.0;
    let (mut sum, mut term, start) = if k.is_multiple_of(2) {
        (0.0, 1.0, 0)
    } else {
        (erfc(half.sqrt()), (2.0 * x / std::f64::consts::PI).sqrt(), 1)
    };
    // Even k: e^{-x/2} Σ_{i<k/2} (x/2)^i / i!. Odd k: erfc(√(x/2)) + e^{-x/2} Σ_{i<(k−1)/2}
    // √(2x/π) x^i / (3·5···(2i+1)).
    let mut i = start;
    while i < k {
        sum += term * (-half).exp();
        term *= x / (i + 2) as f64;
        i += 2;
    }
    sum.min(1.0)
}

/// The complementary error function `erfc(z)`, `z ≥ 0`, as the upper incomplete gamma
/// function `Γ(1/2, z²)/√π`: its series below `z² = 1.5`, Lentz's continued fraction above
/// (Press et al., *Numerical Recipes*, 3rd ed., 6.2).
fn erfc(z: f64) -> f64 {
    // erfc(z) = Γ(1/2, z²)/√π: the series for z² < 1.5, the continued fraction above.
    let x = z * z;
    let sqrt_pi = std::f64::consts::PI.sqrt();
    if x < 1.5 {
        // γ(1/2, x) = x^{1/2} e^{-x} Σ x^n / (1/2 (1/2+1) … (1/2+n)).
        let (mut sum, mut del, mut ap) = (2.0, 2.0, 0.5);
        for _ in 0..200 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-17 {
                break;
            }
        }
        1.0 - sum * (-x).exp() * x.sqrt() / sqrt_pi
    } else {
        // Lentz's continued fraction of Γ(1/2, x).
        let tiny = 1e-300;
        let mut b = x + 0.5;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..300 {
            let an = -(i as f64) * (i as f64 - 0.5);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (-x).exp() * x.sqrt() * h / sqrt_pi
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// χ² survival values against scipy.stats.chi2.sf.
    #[test]
    fn chi_square_sf_matches_scipy() {
        // scipy.stats.chi2.sf(x, k) for these (x, k).
        let cases = [
            (1.0, 1, 0.31731050786291115),
            (3.84, 1, 0.05004352124870519),
            (2.0, 2, 0.36787944117144245),
            (7.814727903251178, 3, 0.05),
            (32.7, 3, 3.725792120628625e-07),
            (0.5, 3, 0.9188914116546758),
            (20.0, 4, 0.0004993992273873336),
            (11.070497693516351, 5, 0.05000000000000007),
            (100.0, 7, 1.0787979671702833e-18),
            (0.001, 1, 0.9747728793699604),
            (0.3, 9, 0.9999966858902002),
        ];
        for (x, k, want) in cases {
            assert_relative_eq!(chi_square_sf(x, k), want, max_relative = 1e-9);
        }
        assert_eq!(chi_square_sf(0.0, 3), 1.0);
        assert!(chi_square_sf(1.0, 0).is_nan());
    }

    /// Paule–Mandel's τ² by hand: equal errors 0.1 and estimates 1.0, 1.05, 0.95 give
    /// Q = 0.5, below its 2 degrees of freedom, so τ² = 0; with equal errors σ the
    /// generalised Q is `Σ (θ_k − θ̄)² / (σ² + τ²) = K − 1`, so `τ² = s² − σ²` (s² the
    /// estimates' sample variance): 1.0 and 2.0 give 0.5 − 0.01. With two close parts whose
    /// errors lie far below the others' (errors 1e-4, 1e-4, 0.01, 0.01; estimates 0, 3e-4,
    /// 1, 2) the generalised Q is K − 1 at τ² and τ is the estimates' spread (0.957), where
    /// DerSimonian–Laird's moment estimate gives 0.022.
    #[test]
    fn between_variance_by_hand() {
        assert_eq!(between_variance(&test("a", vec![1.0, 1.05, 0.95], vec![0.1, 0.1, 0.1])), 0.0);
        assert_relative_eq!(
            between_variance(&test("a", vec![1.0, 2.0], vec![0.1, 0.1])),
            0.49,
            epsilon = 1e-9
        );
        let t = vec![0.0, 3e-4, 1.0, 2.0];
        let tau2 = between_variance(&test("a", t.clone(), vec![1e-4, 1e-4, 0.01, 0.01]));
        let at = [1e-8, 1e-8, 1e-4, 1e-4].map(|v: f64| (v + tau2).sqrt()).to_vec();
        assert_relative_eq!(test("a", t, at).q, 3.0, epsilon = 1e-6);
        assert_relative_eq!(tau2.sqrt(), 0.957318, epsilon = 1e-5);
    }

    /// Agreeing estimates give a large p-value, disagreeing ones a small one; Q by hand.
    #[test]
    fn q_by_hand() {
        let h = test("a", vec![1.0, 1.1, 0.9], vec![0.1, 0.1, 0.1]);
        assert_relative_eq!(h.pooled, 1.0, epsilon = 1e-15);
        assert_relative_eq!(h.q, 2.0, epsilon = 1e-12);
        assert_eq!(h.dof, 2);
        assert_relative_eq!(h.p_value, (-1.0f64).exp(), epsilon = 1e-12);
        let h = test("a", vec![1.0, 2.0], vec![0.1, 0.1]);
        assert!(h.p_value < 1e-10, "{}", h.p_value);
        assert_relative_eq!(h.relative_spread, 0.5 / 1.5, epsilon = 1e-12);
    }
}
