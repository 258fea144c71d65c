//! Coloured residuals that the batch-means covariance cannot take: a dynamic fit whose log
//! is too short for [`MIN_BATCHES`] batches keeps the white covariance, which coloured
//! residuals make too small (issue 43, item 2).
//!
//! Batch means need batches long against the scores' correlation time and at least
//! [`MIN_BATCHES`] of them, each a run of whole blocks of the pass (`problem::batches`), so
//! a dynamic log too short for that (about 1800–2048 samples or fewer, in 256-sample
//! blocks) gets the white covariance whatever its residuals. Where they are strongly coloured (a Ljung–Box statistic above
//! [`STRONG_COLOUR`] times its 1 % critical value) the intervals are then too narrow by an
//! unknown factor: every 20th row of an independent 5 kHz IPM log of short moves (1810
//! samples, the dynamic model at the dq hold, fit 80 % and 93 %, Ljung–Box 13 and 40 times
//! its critical value) put r_s 5.8 % low at |z| 24 with exit 0. The fit is untrusted
//! (`coloured_residuals`), unless it is exact to the noise floor: every free parameter's
//! standard error (nuisance parameters aside) at most [`PARTS_FLOOR`] of its magnitude, the accuracy the consistency
//! checks take for an exact fit (a noise-free log's residuals are the data's rounding and
//! the model's floor, coloured by nature: the first 1000 samples of the shared noise-free
//! logs have Ljung–Box statistics 200–540 times the critical value, an output's fit down to
//! 99.7 %, and standard errors of 2e-8 to 1e-6 of the estimates, which are within 0.006 %).

use super::consistency::PARTS_FLOOR;
use super::problem::MIN_BATCHES;
use super::result::{CovarianceMethod, FitStatistics, ParameterEstimate, Uncertainty, Warning};

/// Ljung–Box statistic, in multiples of its 1 % critical value, above which residuals are
/// strongly coloured: 4 (for white residuals the statistic is about its degrees of
/// freedom, 25 over the 25 lags against a critical value of 44).
pub const STRONG_COLOUR: f64 = 4.0;

/// The untrusted `coloured_residuals` warning of a dynamic fit (`dynamic`: the model has
/// states, so its residuals have a time order) whose `uncertainty` is the white one
/// although an output's residuals are strongly coloured, unless the `parameters` are exact
/// (module documentation); `None` otherwise.
pub(crate) fn unbatched(
    uncertainty: &Uncertainty,
    fit: &FitStatistics,
    parameters: &[ParameterEstimate],
    dynamic: bool,
) -> Option<Warning> {
    let critical = uncertainty.ljung_box_critical;
    let strong = uncertainty.ljung_box.iter().any(|&q| q > STRONG_COLOUR * critical);
    let exact = parameters
        .iter()
        .filter(|p| !p.fixed && !p.nuisance)
        .all(|p| p.std_error <= PARTS_FLOOR * p.value.abs());
    if !dynamic || uncertainty.method != CovarianceMethod::White || !strong || exact {
        return None;
    }
    let statistics: Vec<String> =
        fit.outputs.iter().zip(&uncertainty.ljung_box).map(|(name, q)| format!("{name} {q:.0}")).collect();
    Some(Warning::untrusted(
        "coloured_residuals",
        format!(
            "the residuals are strongly coloured (Ljung–Box {} against {critical:.0} at 1 %), but {} samples are too \
             few for the {MIN_BATCHES} batches of the batch-means covariance: the intervals are the white ones, which \
             coloured residuals make too small by an unknown factor. A longer log, or one sampled faster, gets \
             honest intervals",
            statistics.join(", "),
            fit.samples
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uncertainty(method: CovarianceMethod, ljung_box: [f64; 2]) -> Uncertainty {
        Uncertainty {
            method,
            dof: 3600,
            batches: 0,
            batch_samples: 0,
            ljung_box: ljung_box.to_vec(),
            ljung_box_critical: 44.3,
            jackknife: false,
            restricted: false,
            effective_dof: Vec::new(),
        }
    }

    fn fit(fit_percent: [f64; 2]) -> FitStatistics {
        FitStatistics {
            outputs: vec!["id".into(), "iq".into()],
            output_units: vec!["A".into(), "A".into()],
            fit_percent: fit_percent.to_vec(),
            rms_residual: vec![0.9, 0.6],
            loss: 1.0,
            mse: 1.0,
            aic: 0.0,
            bic: 0.0,
            fpe: 1.0,
            whiteness: Vec::new(),
            samples: 1810,
            dof: 3600,
            counted: None,
            horizon: None,
        }
    }

    fn estimates(relative_std_error: f64) -> Vec<ParameterEstimate> {
        [("r_s", 0.33), ("k_e", 0.42)]
            .map(|(name, value)| ParameterEstimate::free(name, value, relative_std_error * value))
            .to_vec()
    }

    #[test]
    fn strong_colour_under_the_white_covariance_is_untrusted_unless_exact_static_or_batched() {
        let (f, noisy) = (fit([80.1, 93.5]), estimates(2.5e-3));
        let white = uncertainty(CovarianceMethod::White, [592.2, 1790.1]);
        let w = unbatched(&white, &f, &noisy, true).expect("coloured_residuals");
        assert!(w.untrusted && w.code == "coloured_residuals", "{w:?}");
        assert!(
            w.message.contains("id 592, iq 1790 against 44") && w.message.contains("1810 samples"),
            "{}",
            w.message
        );
        // Exact to the noise floor (1e-5), a model without states, batch means taken: none.
        assert!(unbatched(&white, &f, &estimates(1e-5), true).is_none());
        assert!(unbatched(&white, &f, &estimates(1.1e-5), true).is_some());
        assert!(unbatched(&white, &f, &noisy, false).is_none());
        let batched = uncertainty(CovarianceMethod::BatchMeans, [592.2, 1790.1]);
        assert!(unbatched(&batched, &f, &noisy, true).is_none());
        // Coloured, but not strongly: 4 × 44.3 = 177.2.
        let mild = uncertainty(CovarianceMethod::White, [177.0, 60.0]);
        assert!(unbatched(&mild, &f, &noisy, true).is_none());
        let strong = uncertainty(CovarianceMethod::White, [177.5, 60.0]);
        assert!(unbatched(&strong, &f, &noisy, true).is_some());
    }
}
