//! Building a prediction-error problem ([`PemProblem::new`], with a pass when the scaling
//! needs the Jacobian's column norms), and the problem as the solvers see it
//! ([`LeastSquares`]).

use super::kept::{BestPass, Gather, same_point};
use super::{FreeKind, FreeParameter, PemProblem, ProblemOptions, Slot, Term, WeightedData};
use super::{Loss, gram};
use crate::error::{Error, Result};
use crate::estimate::arrowhead::ArrowLayout;
use crate::estimate::scaling::{ParameterScaling, Transform};
use crate::estimate::solver::{LeastSquares, NormalEquations};
use crate::model::GreyBoxModel;
use nalgebra::DVector;

/// Range of an output weight Λ_i: the estimate and its intervals do not depend on the
/// weights' common scale, and a weight beyond 1e±100 overflows or underflows the sums of the
/// covariance (`Λ²` in the sandwich's meat), which then reports intervals of zero width.
pub const OUTPUT_WEIGHT_RANGE: (f64, f64) = (1e-100, 1e100);

impl<'m, M: GreyBoxModel> PemProblem<'m, M> {
    /// Builds the problem: `start` (length n_θ) are the model parameters' start values,
    /// shared by all experiments; parameters named in `options.per_experiment` get one free
    /// copy per experiment; fixed parameters (metadata flag) are held at their start; with
    /// `options.estimate_x0` each experiment's initial state is free, starting from the
    /// measured one.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] for a wrong `start` length, an unknown name in
    /// `per_experiment`, wrong weight lengths, a non-positive output weight (or one outside
    /// [`crate::estimate::OUTPUT_WEIGHT_RANGE`]) or Huber
    /// threshold, no experiment; [`Error::InvalidBounds`], [`Error::StartOutsideBounds`],
    /// [`Error::InvalidParameter`] for unusable bounds or starts; those of the scaling rule.
    pub fn new(
        model: &'m M,
        preps: Vec<WeightedData<M::Inputs>>,
        start: &[f64],
        scaling: &dyn ParameterScaling,
        options: &ProblemOptions,
    ) -> Result<Self> {
        let params = model.parameters();
        let invalid = |option: &str, reason: String| Error::InvalidOption { option: option.into(), reason };
        if start.len() != params.len() {
            let reason = format!(
                "{} values given, model `{}` has {} parameters",
                start.len(),
                model.name(),
                params.len()
            );
            return Err(invalid("start", reason));
        }
        for name in &options.per_experiment {
            if !params.iter().any(|p| &p.name == name) {
                return Err(invalid(
                    "per_experiment",
                    format!("no parameter `{name}` in model `{}`", model.name()),
                ));
            }
        }
        for (p, &v) in params.iter().zip(start) {
            p.check_bounds()?;
            p.check_start(v)?;
        }
        for (prep, _) in &preps {
            crate::simulate::check_inputs(model, prep, start, &prep.x0)?;
        }
        let ny = model.n_outputs();
        let positive = |v: &[f64]| v.len() == ny && v.iter().all(|w| w.is_finite() && *w > 0.0);
        let output_weights = options.output_weights.clone().unwrap_or_else(|| vec![1.0; ny]);
        if !positive(&output_weights) {
            return Err(invalid(
                "output_weights",
                format!("need {ny} positive finite weights, got {output_weights:?}"),
            ));
        }
        if let Some(w) =
            output_weights.iter().find(|w| !(OUTPUT_WEIGHT_RANGE.0..=OUTPUT_WEIGHT_RANGE.1).contains(*w))
        {
            return Err(invalid(
                "output_weights",
                format!(
                    "{w:e} is outside [{:e}, {:e}]: the estimates and intervals do not depend on the weights' common \
                     scale, and one this far from 1 overflows the covariance's sums; give their ratios (e.g. 1,4)",
                    OUTPUT_WEIGHT_RANGE.0, OUTPUT_WEIGHT_RANGE.1
                ),
            ));
        }
        if let Loss::Huber { delta } = &options.loss
            && !positive(delta)
        {
            return Err(invalid("huber", format!("need {ny} positive finite thresholds, got {delta:?}")));
        }
        let n_exp = preps.len();
        if n_exp == 0 {
            return Err(invalid("experiments", "no experiment given".into()));
        }
        if !options.prefilters.is_empty() && options.prefilters.len() != n_exp {
            return Err(invalid(
                "prefilter",
                format!("{} filters for {n_exp} experiments", options.prefilters.len()),
            ));
        }
        let mut free = Vec::new();
        let mut slots = vec![vec![Slot::Fixed(0.0); params.len()]; n_exp];
        for (j, p) in params.iter().enumerate() {
            if p.fixed {
                slots.iter_mut().for_each(|s| s[j] = Slot::Fixed(start[j]));
                continue;
            }
            let transform = scaling.transform(p, start[j], None)?;
            let (lower_p, upper_p) = (transform.to_scaled(p.lower), transform.to_scaled(p.upper));
            let copies: Vec<Option<usize>> = if options.per_experiment.contains(&p.name) {
                (0..n_exp).map(Some).collect()
            } else {
                vec![None]
            };
            for e in copies {
                let g = free.len();
                free.push(FreeParameter {
                    kind: FreeKind::Parameter(j),
                    experiment: e,
                    transform,
                    lower_p,
                    upper_p,
                });
                match e {
                    Some(e) => slots[e][j] = Slot::Free(g),
                    None => slots.iter_mut().for_each(|s| s[j] = Slot::Free(g)),
                }
            }
        }
        let mut terms = Vec::with_capacity(n_exp);
        for (e, ((prep, weights), slots)) in preps.into_iter().zip(slots).enumerate() {
            if let Some(w) = &weights {
                if w.len() != prep.n {
                    return Err(invalid(
                        "weights",
                        format!("experiment `{}`: {} weights for {} samples", prep.name, w.len(), prep.n),
                    ));
                }
                if let Some((k, v)) = w.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v >= 0.0)) {
                    return Err(invalid(
                        "weights",
                        format!("experiment `{}`: weight {v} at sample {k} is not finite and ≥ 0", prep.name),
                    ));
                }
            }
            let x0_free = (options.estimate_x0 && !prep.x0.is_empty()).then(|| {
                let g = free.len();
                // Scale of the state: its RMS over the record (outputs are states for the PMSM).
                let squares: f64 = prep.y.iter().map(|c| gram::dot(c, c)).sum();
                let rms = (squares / (prep.n * prep.y.len()) as f64).sqrt();
                let scale = if rms > 0.0 && rms.is_finite() { rms } else { 1.0 };
                // An initial state the data barely see (its transient weighted out) must
                // not wander off: bound it to ten times the largest measured output.
                let largest = prep.y.iter().map(|c| gram::max_abs(c)).fold(0.0, f64::max);
                let bound = (10.0 * largest + 1.0) / scale;
                for i in 0..prep.x0.len() {
                    free.push(FreeParameter {
                        kind: FreeKind::InitialState(i),
                        experiment: Some(e),
                        transform: Transform::Linear { scale },
                        lower_p: -bound,
                        upper_p: bound,
                    });
                }
                g
            });
            terms.push(Term { prep, weights, slots, x0_free });
        }
        let ny = model.n_outputs();
        let residuals: usize = terms
            .iter()
            .map(|t| ny * (t.prep.n - usize::from(t.x0_free.is_none() && model.n_states() > 0)))
            .sum();
        if residuals < free.len() {
            return Err(invalid(
                "experiments",
                format!(
                    "{residuals} residuals for {} free parameters (model parameters and initial states): \
                     at least as many residuals as parameters are needed, one more for a noise estimate",
                    free.len()
                ),
            ));
        }
        let above = options.structured_above.unwrap_or(super::STRUCTURED_ABOVE);
        let layout = if free.len() > above && options.prefilters.is_empty() {
            let owner = free.iter().map(|f| f.experiment).collect();
            Some(std::sync::Arc::new(ArrowLayout::try_new(owner, n_exp)?))
        } else {
            None
        };
        let mut problem = Self {
            model,
            terms,
            free,
            horizon: options.horizon,
            output_weights,
            loss: options.loss.clone(),
            prefilters: options.prefilters.clone(),
            best: BestPass::default(),
            seed: std::sync::Mutex::default(),
            layout,
        };
        if scaling.needs_column_norms() {
            problem.rescale_by_column_norms(start, scaling)?;
        }
        Ok(problem)
    }

    fn rescale_by_column_norms(&mut self, start: &[f64], scaling: &dyn ParameterScaling) -> Result<()> {
        let p0 = self.start_vector(start);
        let ne = self.normal_equations(&p0)?;
        let params = self.model.parameters();
        for (g, fp) in self.free.iter_mut().enumerate() {
            let FreeKind::Parameter(j) = fp.kind else { continue };
            // Column norm in θ units: ‖∂ŷ/∂θ‖ = ‖∂ŷ/∂p‖ / (dθ/dp).
            let norm = ne.jtj[(g, g)].sqrt() / fp.transform.dtheta_dp(p0[g]).abs();
            let p = &params[j];
            fp.transform = scaling.transform(p, start[j], Some(norm))?;
            fp.lower_p = fp.transform.to_scaled(p.lower);
            fp.upper_p = fp.transform.to_scaled(p.upper);
        }
        // That pass's Grams are chained with the old transforms.
        self.best.clear();
        Ok(())
    }

    /// The normal equations at p ([`normal_equations`](Self::normal_equations)), kept for
    /// the solver: its first request at exactly p (every entry the same bits) takes them
    /// instead of a second pass; the pass's Grams are offered for the statistics as any
    /// pass's are.
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn seeded_normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        let ne = self.normal_equations(p)?;
        *self.seed.lock().unwrap_or_else(|e| e.into_inner()) = Some((p.clone(), ne.clone()));
        Ok(ne)
    }

    /// The seeded normal equations, once, when they were taken at exactly p.
    fn take_seed(&self, p: &DVector<f64>) -> Option<NormalEquations> {
        let mut seed = self.seed.lock().unwrap_or_else(|e| e.into_inner());
        seed.take_if(|(q, _)| same_point(q, p)).map(|(_, ne)| ne)
    }
}

impl<M: GreyBoxModel> LeastSquares for PemProblem<'_, M> {
    fn n_params(&self) -> usize {
        self.n_free()
    }
    fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        self.take_seed(p).map_or_else(|| PemProblem::normal_equations(self, p), Ok)
    }
    /// The normal equations with the raw residuals' lag sums kept beside the pass's Grams:
    /// [`sums`](PemProblem::sums) at this point, if it is the estimate, runs no pass.
    fn normal_equations_likely_last(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        self.take_seed(p).map_or_else(|| self.normal_equations_gathering(p, Gather::GramsAndResiduals), Ok)
    }
    /// The normal-equation pass abandoned once an experiment's running cost exceeds
    /// `bound` (its cost only grows over its blocks, and the experiments' costs add).
    fn normal_equations_below(&self, p: &DVector<f64>, bound: f64) -> Result<Option<NormalEquations>> {
        match self.take_seed(p) {
            Some(ne) => Ok(Some(ne)),
            None => self.normal_equations_bounded(p, Gather::Grams, bound),
        }
    }
    fn cost(&self, p: &DVector<f64>) -> Result<f64> {
        PemProblem::cost(self, p)
    }
    fn directional_gradient(&self, p: &DVector<f64>, q: &DVector<f64>) -> Result<Option<DVector<f64>>> {
        PemProblem::directional_gradient(self, p, q)
    }
    fn root(&self, p: &DVector<f64>) -> Result<Option<crate::estimate::solver::Root>> {
        PemProblem::root(self, p)
    }
    fn keeps_root(&self) -> bool {
        PemProblem::keeps_root(self)
    }
    fn project(&self, p: &mut DVector<f64>) {
        PemProblem::project(self, p)
    }
    fn project_trial(&self, from: &DVector<f64>, p: &mut DVector<f64>) {
        PemProblem::project_trial(self, from, p)
    }
}
