//! The choice between the two voltage holds (MODEL.md §4) and the advice when the data do
//! not settle it.

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{FitResult, PemOptions, StartedFit, Weighting, fit_with_weighting};
use crate::model::GreyBoxModel;
use crate::pmsm::model::interval::VoltageHold;
use rayon::prelude::*;

/// Factor by which the dq hold's loss must be lower than the stator hold's for
/// [`HoldChoice::Auto`](crate::pmsm::HoldChoice::Auto) to choose it.
pub const DQ_DECISIVE: f64 = 2.0;

/// Factor by which the holds' predicted losses (weighed as in the final choice) must differ
/// for [`HoldChoice::Auto`](crate::pmsm::HoldChoice::Auto) to fit the better hold only; closer
/// predictions fit both.
pub const SCREEN_DECISIVE: f64 = 4.0;

pub(crate) fn hold_ambiguity(
    best: &FitResult,
    hold: VoltageHold,
    others: &[(VoltageHold, FitResult)],
    names: &[&str],
) -> Option<String> {
    let (other_hold, other) = others.first()?;
    let ratio = other.fit.loss / best.fit.loss;
    if !hardly_chosen(best.fit.loss, other.fit.loss) {
        return None;
    }
    // Differ by more than their joint uncertainty.
    let (name, z) = largest_difference(best, other, names, None)?;
    (z > HOLD_AMBIGUOUS_Z).then(|| {
        format!(
            "the {hold} and {other_hold} voltage holds fit almost equally well (loss ratio {ratio:.3}) but their {name} \
             differs by {z:.0} standard errors: the log does not say how the voltage was held; a real \
             inverter holds it in the stator frame (--hold stator); this fit used the {hold} hold"
        )
    })
}

/// The parameter of `names` whose estimates in fits `a` and `b` differ by the most standard
/// deviations of their difference, and that many: `|θ_a − θ_b| / √v`, with `v` the
/// difference's variance from `variance` (per name, in `names`' order: the batches' paired
/// jackknife, [`crate::estimate::paired_difference_variance`]) or else the combined
/// `se_a² + se_b²`. A parameter both fits hold alike (fixed, `--fix`: 0/0) is skipped, as is
/// any non-finite ratio; `None` when no name is in both fits with a finite ratio.
pub(crate) fn largest_difference<'n>(
    a: &FitResult,
    b: &FitResult,
    names: &[&'n str],
    variance: Option<&[f64]>,
) -> Option<(&'n str, f64)> {
    let rows = names.iter().enumerate().filter_map(|(i, n)| {
        let (p, q) = (a.parameter(n)?, b.parameter(n)?);
        let sd = match variance {
            Some(v) => v.get(i)?.sqrt(),
            None => p.std_error.hypot(q.std_error),
        };
        Some((*n, p.value - q.value, sd))
    });
    largest_ratio(rows)
}

/// The row `(name, difference, sd)` of the largest finite `|difference / sd|`, and that ratio.
fn largest_ratio<'n>(rows: impl Iterator<Item = (&'n str, f64, f64)>) -> Option<(&'n str, f64)> {
    rows.map(|(n, d, sd)| (n, (d / sd).abs()))
        .filter(|(_, z)| z.is_finite())
        .max_by(|x, y| x.1.total_cmp(&y.1))
}

/// Whether two holds' losses lie within [`DQ_DECISIVE`] of each other: the data hardly
/// choose between them (`false` when their ratio is not a number).
pub(crate) fn hardly_chosen(loss_a: f64, loss_b: f64) -> bool {
    (1.0 / DQ_DECISIVE..DQ_DECISIVE).contains(&(loss_b / loss_a))
}

/// Standard errors by which two holds' estimates may differ, where the data hardly choose
/// between the holds, before the fit is untrusted (`hold_ambiguous`): the output error's
/// estimates at a tie (combined standard errors), and the instrumental variables' at both
/// holds (standard errors of their difference by the batches' paired jackknife,
/// [`crate::pmsm::fit_pmsm_iv_after`]).
pub const HOLD_AMBIGUOUS_Z: f64 = 3.0;

/// What a user does about holds the log cannot tell apart.
pub(crate) const GIVE_THE_HOLD: &str = "give the hold (--hold stator for a drive's inverter, --hold dq for a simulator that holds the dq voltage)";

/// The fits of every hold tried: the chosen one, the others, `(hold, loss, converged)` in
/// fitting order, notes on restarts, and the noise z of the losses' difference when the
/// noise tied them and the stator hold was taken ([`noise_z`]).
pub(crate) struct HoldFits {
    pub best: (VoltageHold, FitResult),
    pub others: Vec<(VoltageHold, FitResult)>,
    pub losses: Vec<(VoltageHold, f64, bool)>,
    pub notes: Vec<String>,
    pub tied: Option<f64>,
}

/// The noise z below which two holds' losses are tied: their difference `|ΔL|` against its
/// standard deviation under the residuals' noise, `√(N |ΔL|/L) / (2 √τ)` (`N` residuals,
/// the lower loss `L`, their integrated autocorrelation time τ; Vuong, *Econometrica* 57
/// (1989) 307–333). Below it the stator hold (how an inverter holds its output, MODEL.md
/// §4) is chosen.
pub const HOLD_TIE_Z: f64 = 2.0;

/// How many standard deviations of its noise two fits' loss difference is: `‖δ‖ / (2 σ √τ)`,
/// with `‖δ‖² = N σ² |ΔL| / L` the squared difference of the two models' predictions that
/// the lower loss `L` implies (`N` residuals of variance `σ²`), and `τ = 1 + 2 Σ ρ_k` the
/// residuals' integrated autocorrelation time (their lags, with a geometric tail beyond the
/// last): the difference of two sums of squares `Σ (r + δ)² − Σ r²` has the mean `‖δ‖²` and
/// the standard deviation `2 σ ‖δ‖ √τ` (the variance of a log-likelihood ratio, as in
/// Vuong's test of non-nested models, *Econometrica* 57 (1989) 307–333). `None` for fits
/// without a positive loss or whiteness.
pub(crate) fn noise_z(a: &FitResult, b: &FitResult) -> Option<f64> {
    loss_z(a, b.fit.loss, residual_time(a)?.max(residual_time(b)?))
}

/// [`noise_z`] of the fit `a` against another fit of the same samples whose loss alone,
/// `other`, is known: τ from `a`'s residuals alone.
pub(crate) fn noise_z_against(a: &FitResult, other: f64) -> Option<f64> {
    loss_z(a, other, residual_time(a)?)
}

/// [`noise_z`] from `a`'s sample count and loss, the other loss `lb` and τ.
fn loss_z(a: &FitResult, lb: f64, tau: f64) -> Option<f64> {
    let la = a.fit.loss;
    let low = la.min(lb);
    let n = (a.fit.samples * a.fit.whiteness.len()) as f64;
    (low > 0.0 && n > 0.0 && la.is_finite() && lb.is_finite())
        .then(|| (n * (la - lb).abs() / low).sqrt() / (2.0 * tau.sqrt()))
}

/// The integrated autocorrelation time of `r`'s residuals, the mean over its outputs.
fn residual_time(r: &FitResult) -> Option<f64> {
    let t: Vec<f64> = r.fit.whiteness.iter().map(|w| integrated_time(&w.autocorrelation)).collect();
    (!t.is_empty()).then(|| t.iter().sum::<f64>() / t.len() as f64)
}

/// `1 + 2 Σ ρ_k` over the lags `rho`, with the geometric tail `ρ_K r / (1 − r)`,
/// `r = ρ_K / ρ_{K−1}`, when the last two decay; at least 1.
fn integrated_time(rho: &[f64]) -> f64 {
    let sum: f64 = rho.iter().sum();
    let tail = match rho {
        [.., p, q] if *q > 0.0 && q < p => q * (q / p) / (1.0 - q / p),
        _ => 0.0,
    };
    (1.0 + 2.0 * (sum + tail)).max(1.0)
}

/// Whether a fit stalled: not converged, or a parameter at a bound.
fn stalled(r: &FitResult) -> bool {
    !r.solver.success || r.parameters.iter().any(|p| p.at_bound)
}

/// The estimate of `names` in a fit.
fn estimate_of(r: &FitResult, names: &[&str]) -> Option<Vec<f64>> {
    names.iter().map(|n| r.parameter(n).map(|p| p.value)).collect()
}

/// The hold whose predicted loss is at least [`SCREEN_DECISIVE`] times lower than every
/// other's, the dq hold's weighed by [`DQ_DECISIVE`] when the logs carry a modulator's
/// reference; `None` when no hold is that clearly better.
fn screen(predicted: &[(VoltageHold, f64)], modulator: bool) -> Option<VoltageHold> {
    let weighed =
        |(h, l): &(VoltageHold, f64)| if *h == VoltageHold::Dq && modulator { DQ_DECISIVE * l } else { *l };
    let best = predicted.iter().min_by(|a, b| weighed(a).total_cmp(&weighed(b)))?;
    let clear = predicted
        .iter()
        .filter(|p| p.0 != best.0)
        .all(|p| weighed(p) >= SCREEN_DECISIVE * weighed(best) && weighed(p) > 0.0);
    clear.then_some(best.0)
}

/// [`fit_holds_screened`] for the models that `make(hold)` builds: each hold's prediction
/// is a [`StartedFit`] of `experiments` (options `pem`, `weighting`), and the fit of the
/// hold it predicted, from the same start, continues it (its start's preparation and
/// normal-equation pass are not repeated: the estimate is the same bits).
///
/// # Errors
/// Those of `make`; as [`fit_holds`] with [`fit_with_weighting`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_holds_of<M: GreyBoxModel>(
    holds: &[VoltageHold],
    start: &[f64],
    names: &[&str],
    modulator: bool,
    make: impl Fn(VoltageHold) -> Result<M>,
    experiments: &[Experiment],
    pem: &PemOptions,
    weighting: &dyn Weighting,
) -> Result<HoldFits> {
    let models = holds.iter().map(|&h| Ok((h, make(h)?))).collect::<Result<Vec<_>>>()?;
    let model = |h: VoltageHold| {
        models
            .iter()
            .find(|(m, _)| *m == h)
            .map(|(_, m)| m)
            .ok_or_else(|| Error::Solver(format!("no {h} hold model")))
    };
    fit_holds_screened(
        holds,
        start,
        names,
        modulator,
        |h, s| StartedFit::new(model(h)?, experiments, s, pem, weighting).map(|f| (f.predicted_loss(), f)),
        |h, s, started: Option<StartedFit<'_, M>>| match started {
            Some(f) => f.fit(),
            None => fit_with_weighting(model(h)?, experiments, s, pem, weighting),
        },
    )
}

/// [`fit_holds`] after a screen: when more than one hold is to be tried, each hold's loss
/// is first predicted at the start by `predict(hold, start)` (one normal-equation pass,
/// [`crate::estimate::predicted_loss`]), which also gives what the fit of that hold from
/// that start continues (`fit_hold(hold, start, Some(it))`); when one hold is clearly better
/// ([`SCREEN_DECISIVE`]) only it is fitted, and if that fit stalls every hold is. A
/// prediction that fails counts as no evidence.
///
/// # Errors
/// As [`fit_holds`].
pub(crate) fn fit_holds_screened<P: Send>(
    holds: &[VoltageHold],
    start: &[f64],
    names: &[&str],
    modulator: bool,
    predict: impl Fn(VoltageHold, &[f64]) -> Result<(f64, P)> + Sync,
    mut fit_hold: impl FnMut(VoltageHold, &[f64], Option<P>) -> Result<FitResult>,
) -> Result<HoldFits> {
    let mut notes = Vec::new();
    // What the predictions prepared, each for the first fit of its hold from `start`.
    let mut seeds: Vec<(VoltageHold, P)> = Vec::new();
    let mut chosen = None;
    if holds.len() > 1 {
        // One normal-equation pass per hold, the holds in parallel.
        let runs: Vec<Option<(VoltageHold, f64, P)>> =
            holds.par_iter().map(|&h| predict(h, start).ok().map(|(l, p)| (h, l, p))).collect();
        let predicted: Option<Vec<(VoltageHold, f64)>> =
            runs.iter().map(|r| r.as_ref().map(|r| (r.0, r.1))).collect();
        seeds = runs.into_iter().flatten().map(|(h, _, p)| (h, p)).collect();
        let listed = |p: &[(VoltageHold, f64)]| {
            p.iter().map(|(h, l)| format!("{h} {l:.6e}")).collect::<Vec<_>>().join(", ")
        };
        if let Some(p) = &predicted
            && let Some(hold) = screen(p, modulator)
        {
            chosen = Some((hold, listed(p)));
        }
    }
    let mut fit_from = |seeds: &mut Vec<(VoltageHold, P)>, h: VoltageHold, s: &[f64]| {
        let seed = seeds.iter().position(|(sh, _)| *sh == h && s == start).map(|i| seeds.swap_remove(i).1);
        fit_hold(h, s, seed)
    };
    if let Some((hold, listed)) = chosen {
        seeds.retain(|(h, _)| *h == hold);
        let mut fits = fit_holds(&[hold], start, names, modulator, |h, s| fit_from(&mut seeds, h, s))?;
        if !stalled(&fits.best.1) {
            fits.notes.push(format!(
                "voltage hold chosen automatically: the {hold} hold, whose loss the Gauss-Newton step from the \
                 start predicts at least {SCREEN_DECISIVE} times lower{} (predicted losses {listed}); only it was fitted",
                if modulator { " (the dq hold's weighed ×2: the log carries a modulator's reference)" } else { "" },
            ));
            return Ok(fits);
        }
        notes.push(format!(
            "the {hold} hold, chosen from the predicted losses ({listed}), stalled: every hold fitted"
        ));
    }
    // Only the first hold's fit starts from `start` (a restart from it may, later).
    seeds.retain(|(h, _)| Some(h) == holds.first());
    let mut fits = fit_holds(holds, start, names, modulator, |h, s| fit_from(&mut seeds, h, s))?;
    notes.append(&mut fits.notes);
    fits.notes = notes;
    Ok(fits)
}

/// Fits every hold in `holds` with `fit_hold(hold, start)` (the second from the first's
/// estimate when that converged), restarts a fit that stalled (not converged, or at a bound)
/// from every other start available (the other hold's estimate, the given start) and keeps
/// its lowest loss, then chooses: a converged fit over one that is not, else the lower loss,
/// the dq hold's multiplied by [`DQ_DECISIVE`] when the logs carry a modulator's reference
/// (`modulator`: an inverter holds its output in the stator frame).
///
/// # Errors
/// Those of `fit_hold`; [`Error::InvalidOption`] for no hold.
pub(crate) fn fit_holds(
    holds: &[VoltageHold],
    start: &[f64],
    names: &[&str],
    modulator: bool,
    mut fit_hold: impl FnMut(VoltageHold, &[f64]) -> Result<FitResult>,
) -> Result<HoldFits> {
    let mut fits: Vec<(VoltageHold, FitResult)> = Vec::new();
    // The start each fit took: a restart from it again would only repeat the fit.
    let mut used: Vec<Vec<f64>> = Vec::new();
    for &hold in holds {
        let s = fits
            .last()
            .filter(|(_, r)| !stalled(r))
            .and_then(|(_, r)| estimate_of(r, names))
            .unwrap_or_else(|| start.to_vec());
        fits.push((hold, fit_hold(hold, &s)?));
        used.push(s);
    }
    let mut notes = Vec::new();
    for i in 0..fits.len() {
        if !stalled(&fits[i].1) {
            continue;
        }
        let mut starts: Vec<Vec<f64>> = fits
            .iter()
            .enumerate()
            .filter(|(j, (_, r))| *j != i && !stalled(r))
            .filter_map(|(_, (_, r))| estimate_of(r, names))
            .collect();
        starts.push(start.to_vec());
        starts.retain(|s| *s != used[i]);
        let before = fits[i].1.fit.loss;
        if starts.is_empty() {
            notes.push(format!("the {} hold fit stalled; no other start to restart it from", fits[i].0));
            continue;
        }
        for s in starts {
            let r = fit_hold(fits[i].0, &s)?;
            let current = &fits[i].1;
            if (r.solver.success && !current.solver.success)
                || (!stalled(&r) && r.fit.loss < current.fit.loss)
                || (stalled(current) && !stalled(&r))
            {
                fits[i].1 = r;
            }
        }
        notes.push(format!(
            "the {} hold fit stalled ({}); restarted from the other estimates: loss {before:.6e} -> {:.6e}{}",
            fits[i].0,
            if fits[i].1.solver.success { "at a bound" } else { "not converged" },
            fits[i].1.fit.loss,
            if stalled(&fits[i].1) { ", still stalled" } else { "" }
        ));
    }
    let losses = fits.iter().map(|(h, r)| (*h, r.fit.loss, r.solver.success)).collect();
    let weighed =
        |h: VoltageHold, loss: f64| if h == VoltageHold::Dq && modulator { DQ_DECISIVE * loss } else { loss };
    let key = |(h, r): &(VoltageHold, FitResult)| (stalled(r), weighed(*h, r.fit.loss));
    // Two unstalled holds whose losses the noise ties, without a modulator's reference to
    // weigh them: the stator hold.
    let stator = fits.iter().position(|(h, _)| *h == VoltageHold::Stator);
    let tied = match &fits[..] {
        [(_, a), (_, b)] if !modulator && !stalled(a) && !stalled(b) && stator.is_some() => {
            noise_z(a, b).filter(|z| *z < HOLD_TIE_Z)
        }
        _ => None,
    };
    let i = match (tied, stator) {
        (Some(_), Some(i)) => Some(i),
        _ => (0..fits.len()).min_by(|&a, &b| {
            let (ka, kb) = (key(&fits[a]), key(&fits[b]));
            ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
        }),
    }
    .ok_or_else(|| Error::InvalidOption { option: "hold".into(), reason: "no hold fitted".into() })?;
    let best = fits.remove(i);
    Ok(HoldFits { best, others: fits, losses, notes, tied })
}

#[cfg(test)]
mod tests {
    use super::{integrated_time, largest_ratio};

    /// A parameter both fits hold fixed (difference 0, standard deviation 0) does not hide
    /// one that differs: 0/0 is skipped, not ranked above every ratio by `total_cmp`.
    #[test]
    fn a_fixed_parameter_does_not_hide_a_difference() {
        let rows = [("r_s", 0.0, 0.0), ("l_s", 5.0e-4, 1.0e-4), ("k_e", 1.0e-3, 1.0e-3)];
        assert_eq!(largest_ratio(rows.into_iter()), Some(("l_s", 5.0)));
        assert_eq!(largest_ratio([("r_s", 0.0, 0.0)].into_iter()), None);
    }

    /// AR(1) residuals `ρ_k = a^k`: `1 + 2 Σ a^k = (1 + a)/(1 − a)`, the lags held and the
    /// geometric tail beyond them; white residuals 1; an oscillating tail adds nothing.
    #[test]
    fn the_integrated_time_of_ar1_residuals() {
        for a in [0.3, 0.9, 0.98] {
            let rho: Vec<f64> = (1..=25).map(|k| f64::powi(a, k)).collect();
            let tau = integrated_time(&rho);
            assert!((tau / ((1.0 + a) / (1.0 - a)) - 1.0).abs() < 1e-9, "a {a}: τ {tau}");
        }
        assert_eq!(integrated_time(&[0.0; 25]), 1.0);
        assert!((integrated_time(&[0.2, -0.1, 0.05]) - 1.3).abs() < 1e-12);
        assert_eq!(integrated_time(&[-0.4, 0.1, -0.05]), 1.0);
    }
}
