//! A flux map's self-consistency (issue 43, item 1): the saturation model refitted on four
//! regions of operating points, Cochran's Q of each coefficient over them, and where they
//! disagree the coefficients' intervals widened by the regions' spread.
//!
//! Why: a flux map's residuals are not noise but model error (on the measured Baldor map
//! Ljung–Box 3982 against 44), and a map of a few hundred points is too small for batch
//! means, so the coefficients' standard errors describe nothing real: ψ_f came out ± 0.3 %.
//! A model that describes the map gives the same coefficients on every region of it; a
//! model too stiff for the map gives each region its own. The spread of those fits beyond
//! their standard errors, the between-region variance `τ²` of random-effects
//! meta-analysis (Paule & Mandel 1982, [`between_variance`]), is added to each
//! coefficient's variance: the interval then covers what the coefficient would be had
//! another part of the map been measured, the question the standard error was meant to
//! answer. With τ² estimated from four regions, the interval takes Student's t quantile
//! with K − 1 degrees of freedom (K the regions that estimated the coefficient) rather than
//! the normal 1.96, as random-effects meta-analysis does with few studies (Hartung &
//! Knapp, *Stat. Med.* 20, 2001; IntHout, Ioannidis & Borm, *BMC Med. Res. Methodol.* 14,
//! 2014: the normal quantile undercovers with fewer than about 20 studies).

use crate::data::{Channel, Experiment};
use crate::estimate::{
    FitResult, Homogeneity, PARTS_FLOOR, PARTS_LEVEL, PemOptions, disagreement_of, fit,
    homogeneity_where_estimated, widened_by_parts,
};
use crate::pmsm::model::flux_map::FluxMapModel;
use crate::pmsm::model::saturation::SaturationExponents;
use serde::{Deserialize, Serialize};

/// Fewest points a region must hold for the check to run (each fits the six coefficients).
pub const REGION_POINTS: usize = 24;

/// A coefficient's interval widened by the regions' spread.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Widened {
    /// The coefficient's name.
    pub name: String,
    /// The whole map's estimate \[its unit\].
    pub value: f64,
    /// The whole map's standard error \[its unit\].
    pub std_error: f64,
    /// The between-region standard deviation `τ` \[its unit\].
    pub tau: f64,
    /// The 95 % interval `value ± t_{0.975, K−1} √(std_error² + τ²)` \[its unit\] (K the
    /// regions that estimated the coefficient; [`crate::estimate::t_quantile_975`]).
    pub interval: [f64; 2],
}

/// The saturation model refitted on regions of the map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RegionCheck {
    /// The regions, in words, with their point counts.
    pub regions: Vec<String>,
    /// Cochran's Q of each coefficient the regions estimate.
    pub tests: Vec<Homogeneity>,
    /// The coefficients on which the regions disagree (family level
    /// [`PARTS_LEVEL`](crate::estimate::PARTS_LEVEL), Bonferroni), in words; `None` when
    /// they agree.
    pub disagreement: Option<String>,
    /// Where they disagree: every tested coefficient's interval widened by `τ` (empty when
    /// they agree: the whole map's intervals stand; a coefficient at its bound on the whole
    /// map is left out).
    pub widened: Vec<Widened>,
}

/// Which of the four regions a point `(i_d, i_q)` lies in: `i_d` at or below the map's
/// median `d_mid` or above it, `|i_q|` at or below the median `q_mid` of `|i_q|` or above
/// (so that every region holds both signs of `i_q`, and the q-axis' odd symmetry).
fn region([d, q]: [f64; 2], d_mid: f64, q_mid: f64) -> usize {
    2 * usize::from(d > d_mid) + usize::from(q.abs() > q_mid)
}

/// The median of `v` (the lower middle for an even count).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[(v.len() - 1) / 2]
}

/// The saturation model at exponents `e` refitted from `theta` (its six coefficients, model
/// order) on the map's points where `keep(k)` holds, as a data set of their own named `name`
/// (the rows of `i_d, i_q, psi_d, psi_q`): the cross-validation's folds and the regions.
/// `None` without those channels or six coefficients; `Some(Err)` when the fit fails.
pub(super) fn refit_where(
    map: &Experiment,
    e: SaturationExponents,
    theta: &[f64],
    name: String,
    keep: &dyn Fn(usize) -> bool,
) -> Option<crate::Result<FitResult>> {
    let channels: Vec<Channel> = ["i_d", "i_q", "psi_d", "psi_q"]
        .iter()
        .map(|n| {
            let c = map.get(n)?;
            let v: Vec<f64> =
                c.values.iter().enumerate().filter(|(k, _)| keep(*k)).map(|(_, v)| *v).collect();
            Some(Channel::new(*n, c.unit.clone(), v))
        })
        .collect::<Option<_>>()?;
    let part = Experiment::try_new(name, map.h(), channels).ok()?;
    let start: [f64; 6] = theta.try_into().ok()?;
    Some(fit(&FluxMapModel::new(e, &start), std::slice::from_ref(&part), theta, &PemOptions::default()))
}

/// The map's regions refitted at exponents `e` from the whole map's fit `result` (module
/// documentation). `None` when the map lacks the channels, a region holds fewer than
/// [`REGION_POINTS`] points, or fewer than two regions could be fitted.
pub(crate) fn check(map: &Experiment, e: SaturationExponents, result: &FitResult) -> Option<RegionCheck> {
    let (i_d, i_q) = (map.channel("i_d").ok()?, map.channel("i_q").ok()?);
    // `+ 0.0` writes a grid's −0 as 0.
    let d_mid = median(i_d.to_vec()) + 0.0;
    let q_mid = median(i_q.iter().map(|q| q.abs()).collect()) + 0.0;
    let of = |k: usize| region([i_d[k], i_q[k]], d_mid, q_mid);
    let theta: Vec<f64> = result.parameters.iter().map(|p| p.value).collect();
    let mut regions = Vec::new();
    let mut fits = Vec::new();
    for r in 0..4 {
        let count = (0..map.len()).filter(|k| of(*k) == r).count();
        if count < REGION_POINTS {
            return None;
        }
        let (d, q) = (if r >= 2 { ">" } else { "≤" }, if r % 2 == 1 { ">" } else { "≤" });
        regions.push(format!("i_d {d} {d_mid:.2} A, |i_q| {q} {q_mid:.2} A ({count} points)"));
        let name = format!("{}#region{}", map.name(), r + 1);
        if let Ok(f) = refit_where(map, e, &theta, name, &|k| of(k) == r)? {
            fits.push(f);
        }
    }
    if fits.len() < 2 {
        return None;
    }
    let tests = homogeneity_where_estimated(&fits, PARTS_FLOOR);
    let disagreement = disagreement_of(&tests, PARTS_FLOOR, PARTS_LEVEL);
    let widened = match disagreement {
        None => Vec::new(),
        Some(_) => tests
            .iter()
            .filter_map(|h| {
                // A coefficient at its bound on the whole map has no interval to widen.
                let p = result.parameter(&h.name).filter(|p| p.std_error.is_finite())?;
                let (tau, _, half) = widened_by_parts(p.std_error, h);
                Some(Widened {
                    name: h.name.clone(),
                    value: p.value,
                    std_error: p.std_error,
                    tau,
                    interval: [p.value - half, p.value + half],
                })
            })
            .collect(),
    };
    Some(RegionCheck { regions, tests, disagreement, widened })
}

/// [`check`], or where it cannot run (a map too small to split) a note saying so.
pub(crate) fn check_or_note(
    map: &Experiment,
    e: SaturationExponents,
    result: &FitResult,
) -> (Option<RegionCheck>, Option<String>) {
    match check(map, e, result) {
        Some(r) => (Some(r), None),
        None => (
            None,
            Some(format!(
                "the map's regions were not refitted (each needs at least {REGION_POINTS} points, or two regions \
                 their fits): whether the coefficients hold over the whole map is not checked"
            )),
        ),
    }
}

impl std::fmt::Display for RegionCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let smallest = self.tests.iter().map(|h| h.p_value).fold(f64::INFINITY, f64::min);
        writeln!(
            f,
            "\nthe saturation model refitted on {} regions of the map: {}",
            self.regions.len(),
            self.regions.join("; ")
        )?;
        let Some(why) = &self.disagreement else {
            return writeln!(
                f,
                "they agree (Cochran's Q, smallest p {smallest:.2e}; family level {PARTS_LEVEL:e}): the coefficients' \
                 intervals stand"
            );
        };
        writeln!(
            f,
            "they disagree (Cochran's Q, family level {PARTS_LEVEL:e}): {why}. The coefficients depend on where in \
             the map they are fitted, beyond their standard errors: 95 % intervals with the regions' spread τ \
             (Paule–Mandel) in quadrature:"
        )?;
        writeln!(f, "{:<8} {:>14} {:>11} {:>11}   95 % interval", "", "value", "std error", "τ")?;
        for w in &self.widened {
            writeln!(
                f,
                "{:<8} {:>14.6e} {:>11.3e} {:>11.3e}   [{:.6e}, {:.6e}]",
                w.name, w.value, w.std_error, w.tau, w.interval[0], w.interval[1]
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each quadrant of the split gets its own region, both signs of `i_q` together.
    #[test]
    fn regions_split_at_the_medians() {
        assert_eq!(region([-4.0, 3.0], 0.0, 5.0), 0);
        assert_eq!(region([-4.0, -3.0], 0.0, 5.0), 0);
        assert_eq!(region([-4.0, -7.0], 0.0, 5.0), 1);
        assert_eq!(region([2.0, 5.0], 0.0, 5.0), 2);
        assert_eq!(region([2.0, -9.0], 0.0, 5.0), 3);
        assert_eq!(median(vec![3.0, 1.0, 2.0, 4.0]), 2.0);
    }
}
