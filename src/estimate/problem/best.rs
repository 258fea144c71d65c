//! The normal-equation pass at the lowest cost met so far, kept for the statistics.
//!
//! With the quadratic loss, unit sample weights and no prefilter, the statistics of a fit
//! (MODEL.md §5) need, besides the raw residuals, only sums that the normal-equation pass
//! at the estimate has already formed: each output's Gram of the local Jacobian columns
//! and its residual (`JᵀJ`, `Jᵀε`, `εᵀε` per output). The solver's estimate is the point
//! of lowest cost it evaluated, so the problem keeps that pass's Grams, and
//! [`PemProblem::sums`](super::PemProblem::sums) at that very point (compared bit by bit)
//! takes them instead of a second pass with sensitivities. A pass the solver expects to be
//! its last ([`LeastSquares::normal_equations_likely_last`]) also streams the raw
//! residuals into the whiteness test's lag sums: if it is the estimate, the statistics run
//! no pass at all; if not, they cost that pass a few ns a sample (the lag products).
//!
//! [`LeastSquares::normal_equations_likely_last`]: crate::estimate::solver::LeastSquares::normal_equations_likely_last

use super::PemProblem;
use super::accumulate::Accumulator;
use super::kept::ExperimentGrams;
use super::local::Pass;
use crate::error::Result;
use crate::model::GreyBoxModel;
use nalgebra::DVector;

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// Whether [`sums`](PemProblem::sums) at p takes every sum from a pass already made
    /// there (the normal-equation pass the solver flagged as its last, at exactly p: every
    /// entry the same bits), so that the statistics simulate nothing.
    pub fn statistics_kept(&self, p: &DVector<f64>) -> bool {
        self.best.at(p).is_some_and(|k| k.iter().all(|e| e.residuals.is_some()))
    }

    /// Experiment e's statistics sums at p from the kept pass's Grams `kept` (quadratic
    /// loss, unit weights, no prefilter): the sums of the statistics pass, whose Gram of
    /// output i serves `JᵀWJ` (Λ_i G_i), the bread (the same) and the meat (Λ_i² G_i);
    /// the raw residuals' lag sums are the pass's when it gathered them; otherwise one
    /// simulation without sensitivities streams the raw residuals into them.
    ///
    /// # Errors
    /// Those of the simulation: invalid θ, [`crate::Error::SimulationDiverged`].
    pub(super) fn kept_sums(
        &self,
        e: usize,
        p: &DVector<f64>,
        kept: &ExperimentGrams,
        acc: &mut Accumulator,
    ) -> Result<()> {
        let ny = self.model.n_outputs();
        let n = match &kept.residuals {
            Some(r) => {
                acc.add_lag_sums(r.lags.clone());
                r.n
            }
            None => {
                let mut n = 0;
                self.pass_blocks(e, p, Pass::RAW_RESIDUALS, |ch| {
                    n += ch.len - ch.lo;
                    for i in 0..ny {
                        acc.add_residuals(i, ch.eps(i));
                    }
                    Ok(())
                })?;
                n
            }
        };
        acc.add_samples(n);
        let m = kept.map.len();
        let mut jtj = vec![0.0; m * m];
        let mut meat = vec![vec![0.0; m * m]; ny];
        for (i, (g, meat)) in kept.grams.iter().zip(meat.iter_mut()).enumerate() {
            let lambda = self.output_weights[i];
            let sse = g[m * (m + 1) + m];
            acc.add_output_sums(i, 0.5 * lambda * sse, lambda * sse, sse, sse, n);
            for a in 0..m {
                for b in a..m {
                    jtj[a * m + b] += lambda * g[a * (m + 1) + b];
                    meat[a * m + b] += lambda * lambda * g[a * (m + 1) + b];
                }
            }
        }
        acc.add_local(&kept.map, &jtj, &jtj, &meat);
        acc.add_block_scores(&kept.map, &kept.scores);
        Ok(())
    }
}
