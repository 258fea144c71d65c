//! The prediction-error problem: experiments, the map from the optimiser's scaled vector
//! p to each experiment's θ (and, on request, initial state), and one-pass evaluation of
//! the cost and normal equations.
//!
//! Criterion (MODEL.md §5; Ljung, *System Identification*, 2nd ed., ch. 7 and 15.2):
//! `V(p) = Σ_e Σ_k β_ek Σ_i Λ_i ρ(ε_eki)`, `ε = y − ŷ(θ(p))`, with `ρ(ε) = ½ε²`
//! (quadratic) or Huber's `ρ(ε) = ½ε²` for `|ε| ≤ δ`, `δ|ε| − ½δ²` beyond (Huber 1981,
//! *Robust Statistics*, 7.8). The Jacobian is `J = ∂ŷ/∂p` (so `∂ε/∂p = −J`) and the
//! Gauss-Newton step solves `JᵀWJ δ = JᵀWψ(ε)`; for Huber the weight of a residual
//! beyond δ is `δ/|ε|` (iteratively reweighted least squares).

use crate::error::{Error, Result};
use crate::estimate::filter::Butterworth;
use crate::estimate::scaling::{ParameterScaling, Transform};
use crate::model::{GreyBoxModel, Prepared};
use crate::simulate::{SimOptions, simulate, visit_sensitivities};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// One experiment's prepared data with optional per-sample weights β_k (length N).
pub type WeightedData<I> = (Prepared<I>, Option<Vec<f64>>);

/// One experiment's share of the cost and normal equations (cost, `JᵀWJ` row-major, `JᵀWψ`).
type Partial = (f64, Vec<f64>, Vec<f64>);

/// The loss ρ applied to each residual.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Loss {
    /// `ρ(ε) = ½ ε²`.
    #[default]
    Quadratic,
    /// Huber's loss with threshold δ_i per output [output unit], length n_y.
    Huber {
        /// Thresholds δ_i > 0.
        delta: Vec<f64>,
    },
}

impl Loss {
    /// `(ρ(ε), ψ(ε), IRLS weight ψ(ε)/ε, ψ'(ε))` for residual `e` of output `i`.
    #[inline]
    fn eval(&self, i: usize, e: f64) -> (f64, f64, f64, f64) {
        match self {
            Self::Quadratic => (0.5 * e * e, e, 1.0, 1.0),
            Self::Huber { delta } => {
                let (d, a) = (delta[i], e.abs());
                if a <= d {
                    (0.5 * e * e, e, 1.0, 1.0)
                } else {
                    (d * a - 0.5 * d * d, d * e.signum(), d / a, 0.0)
                }
            }
        }
    }
}

/// Options of a [`PemProblem`] beyond the model, data and start.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProblemOptions {
    /// Parameters estimated separately for each experiment, by name.
    pub per_experiment: Vec<String>,
    /// k-step-ahead prediction horizon; `None` = simulation (output error).
    pub horizon: Option<usize>,
    /// Output weights Λ (length n_y), `None` = 1.
    pub output_weights: Option<Vec<f64>>,
    /// Residual loss.
    pub loss: Loss,
    /// Estimate each experiment's initial state x₀ (n_x extra parameters per experiment).
    pub estimate_x0: bool,
    /// Residual prefilter L(q), one per experiment (its sample time), or empty for none:
    /// `ε_f = L(q) ε` and `J_f = L(q) J`, causal, from rest (MODEL.md §5).
    pub prefilters: Vec<Butterworth>,
}

/// Where each model parameter of one experiment comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Slot {
    /// Held at this value [parameter unit].
    Fixed(f64),
    /// The optimiser's free parameter with this index.
    Free(usize),
}

/// What a free parameter of the optimisation is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FreeKind {
    /// Model parameter with this index.
    Parameter(usize),
    /// Component of the initial state of one experiment.
    InitialState(usize),
}

/// One free parameter of the optimisation.
#[derive(Clone, Debug)]
pub struct FreeParameter {
    /// Model parameter or initial-state component.
    pub kind: FreeKind,
    /// Experiment index for a per-experiment parameter or initial state; `None` when shared.
    pub experiment: Option<usize>,
    /// θ ↔ p map.
    pub transform: Transform,
    /// Bounds in scaled space `[T⁻¹(lower), T⁻¹(upper)]`.
    pub lower_p: f64,
    /// Upper bound in scaled space.
    pub upper_p: f64,
}

/// One experiment's data within a problem.
#[derive(Debug)]
pub struct Term<I> {
    /// Prepared data.
    pub prep: Prepared<I>,
    /// Per-sample weights β_k (length N), `None` = 1.
    pub weights: Option<Vec<f64>>,
    /// Source of every model parameter for this experiment, length n_θ.
    pub slots: Vec<Slot>,
    /// Index of the first of n_x free initial-state parameters, when estimated.
    pub x0_free: Option<usize>,
}

/// Cost and normal equations at one point (scaled space, length n_p).
#[derive(Clone, Debug)]
pub struct NormalEquations {
    /// `V = Σ w ρ(ε)`.
    pub cost: f64,
    /// `JᵀWJ` (IRLS-weighted for Huber), `n_p × n_p`.
    pub jtj: DMatrix<f64>,
    /// `JᵀWψ(ε)`, length n_p.
    pub jtr: DVector<f64>,
}

/// Sums at the estimate from which the statistics of a fit follow.
#[derive(Clone, Debug)]
pub struct Sums {
    /// Cost `V`.
    pub cost: f64,
    /// Weighted residual sum of squares `Σ w ε²` (the E² of the error index).
    pub e2_weighted: f64,
    /// Unweighted residual sum of squares per output, length n_y.
    pub sse: Vec<f64>,
    /// Number of residual samples per output (same for every output).
    pub count: usize,
    /// `Σ (y − ȳ)²` per output, length n_y.
    pub sst: Vec<f64>,
    /// `JᵀWJ` (scaled space): the information matrix of the error index and diagnostics.
    pub jtj: DMatrix<f64>,
    /// Bread `A = Σ w ψ'(ε) JᵀJ` of the sandwich covariance `A⁻¹ B A⁻¹`.
    pub bread: DMatrix<f64>,
    /// Meat `B`: `Σ_i σ̂_i² Σ_k w² J_kiᵀJ_ki` (quadratic), `N/(N − n_p) Σ w² ψ² JᵀJ` (Huber);
    /// with a residual prefilter L(q), `Σ_i σ̂_i² gᵢᵀgᵢ` with `gᵢ = Lᵀ(W J_f)` (the
    /// time-reversed filter applied to the weighted filtered Jacobian) and σ̂ from the raw
    /// residuals: exact for white raw residuals.
    pub meat: DMatrix<f64>,
}

/// A prediction-error problem over one or more experiments of one model.
pub struct PemProblem<'m, M: GreyBoxModel> {
    model: &'m M,
    terms: Vec<Term<M::Inputs>>,
    free: Vec<FreeParameter>,
    horizon: Option<usize>,
    output_weights: Vec<f64>,
    loss: Loss,
    prefilters: Vec<Butterworth>,
}

impl<'m, M: GreyBoxModel> PemProblem<'m, M> {
    /// Builds the problem: `start` (length n_θ) are the model parameters' start values,
    /// shared by all experiments; parameters named in `options.per_experiment` get one free
    /// copy per experiment; fixed parameters (metadata flag) are held at their start; with
    /// `options.estimate_x0` each experiment's initial state is free, starting from the
    /// measured one.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] for a wrong `start` length, an unknown name in
    /// `per_experiment`, wrong weight lengths, a non-positive output weight or Huber
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
                let rms = (prep.y.iter().map(|v| v * v).sum::<f64>() / prep.y.len() as f64).sqrt();
                let scale = if rms > 0.0 && rms.is_finite() { rms } else { 1.0 };
                // An initial state the data barely see (its transient weighted out) must
                // not wander off: bound it to ten times the largest measured output.
                let bound = (10.0 * prep.y.iter().fold(0.0f64, |m, v| m.max(v.abs())) + 1.0) / scale;
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
        let mut problem = Self {
            model,
            terms,
            free,
            horizon: options.horizon,
            output_weights,
            loss: options.loss.clone(),
            prefilters: options.prefilters.clone(),
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
        Ok(())
    }

    /// The model.
    pub fn model(&self) -> &M {
        self.model
    }
    /// The experiments' terms.
    pub fn terms(&self) -> &[Term<M::Inputs>] {
        &self.terms
    }
    /// The free parameters, in the order of the scaled vector p.
    pub fn free(&self) -> &[FreeParameter] {
        &self.free
    }
    /// Number of free parameters n_p.
    pub fn n_free(&self) -> usize {
        self.free.len()
    }
    /// The k-step prediction horizon (`None`: simulation).
    pub fn horizon(&self) -> Option<usize> {
        self.horizon
    }
    /// The residual loss.
    pub fn loss(&self) -> &Loss {
        &self.loss
    }

    /// Scaled start vector p₀ (length n_p) for model start values θ₀ (initial states from
    /// the measurement).
    ///
    /// # Panics
    /// If `start` has fewer than n_θ entries.
    pub fn start_vector(&self, start: &[f64]) -> DVector<f64> {
        DVector::from_iterator(
            self.free.len(),
            self.free.iter().map(|f| match (f.kind, f.experiment) {
                (FreeKind::Parameter(j), _) => f.transform.to_scaled(start[j]),
                (FreeKind::InitialState(i), Some(e)) => f.transform.to_scaled(self.terms[e].prep.x0[i]),
                (FreeKind::InitialState(_), None) => 0.0,
            }),
        )
    }

    /// θ of experiment `e` at scaled point p (length n_p); returns length n_θ.
    ///
    /// # Panics
    /// If `e` is not an experiment index or p is shorter than n_p.
    pub fn theta(&self, e: usize, p: &DVector<f64>) -> Vec<f64> {
        self.terms[e]
            .slots
            .iter()
            .map(|s| match *s {
                Slot::Fixed(v) => v,
                Slot::Free(g) => self.free[g].transform.to_theta(p[g]),
            })
            .collect()
    }

    /// Initial state of experiment `e` at p (measured, or estimated).
    pub fn x0(&self, e: usize, p: &DVector<f64>) -> Vec<f64> {
        let term = &self.terms[e];
        match term.x0_free {
            Some(g) => {
                (0..term.prep.x0.len()).map(|i| self.free[g + i].transform.to_theta(p[g + i])).collect()
            }
            None => term.prep.x0.clone(),
        }
    }

    /// First sample of experiment e that counts: 1 when a dynamic model starts from the
    /// measured first state (its residual is zero by construction), 0 otherwise (estimated
    /// initial state, or a static model).
    pub fn first_sample(&self, e: usize) -> usize {
        usize::from(self.terms[e].x0_free.is_none() && self.model.n_states() > 0)
    }

    /// Projects p onto the bounds (componentwise clamp in scaled space).
    pub fn project(&self, p: &mut DVector<f64>) {
        for (g, f) in self.free.iter().enumerate() {
            p[g] = p[g].clamp(f.lower_p, f.upper_p);
        }
    }

    /// `dθ/dp` for every model parameter of experiment e, with its global index.
    fn chain(&self, e: usize, p: &DVector<f64>) -> (Vec<Option<usize>>, Vec<f64>) {
        self.terms[e]
            .slots
            .iter()
            .map(|s| match *s {
                Slot::Fixed(_) => (None, 0.0),
                Slot::Free(g) => (Some(g), self.free[g].transform.dtheta_dp(p[g])),
            })
            .unzip()
    }

    fn fd_scale(&self, e: usize, p: &DVector<f64>) -> Vec<f64> {
        let theta = self.theta(e, p);
        let (_, d) = self.chain(e, p);
        d.iter().zip(&theta).map(|(&d, &t)| if d != 0.0 { d.abs() } else { t.abs().max(1e-12) }).collect()
    }

    /// Runs `f(k, ε_k, w_k, J_k)` over every counted sample of experiment e, where
    /// `J_k = ∂ŷ_k/∂p` is row-major `n_y × n_p` and `w_k[i] = β_k Λ_i`.
    fn pass<F>(&self, e: usize, p: &DVector<f64>, f: F) -> Result<()>
    where
        F: FnMut(usize, &[f64], &[f64], &[f64]),
    {
        self.pass_with(e, p, true, f)
    }

    /// As [`pass`](Self::pass); `filtered = false` skips the residual prefilter.
    fn pass_with<F>(&self, e: usize, p: &DVector<f64>, filtered: bool, mut f: F) -> Result<()>
    where
        F: FnMut(usize, &[f64], &[f64], &[f64]),
    {
        let term = &self.terms[e];
        let (ny, np) = (self.model.n_outputs(), self.free.len());
        let theta = self.theta(e, p);
        let (global, dtheta) = self.chain(e, p);
        let scale = self.fd_scale(e, p);
        let x0 = self.x0(e, p);
        let nx = x0.len();
        let x0_chain: Vec<(usize, f64)> = term
            .x0_free
            .map(|g| (0..nx).map(|i| (g + i, self.free[g + i].transform.dtheta_dp(p[g + i]))).collect())
            .unwrap_or_default();
        let mut eps = vec![0.0; ny];
        let mut jac = vec![0.0; ny * np];
        let mut w = vec![0.0; ny];
        let nth = theta.len();
        let first = self.first_sample(e);
        let mut filter = self.prefilters.get(e).filter(|_| filtered).map(|l| ResidualFilter::new(l, ny, np));
        let visit = |k: usize, yhat: &[f64], dy: &[f64], dy0: &[f64]| {
            if k < first {
                return;
            }
            let y = term.prep.y_at(k, ny);
            let beta = term.weights.as_ref().map_or(1.0, |b| b[k]);
            jac.fill(0.0);
            for i in 0..ny {
                eps[i] = y[i] - yhat[i];
                w[i] = beta * self.output_weights[i];
                for j in 0..nth {
                    if let Some(g) = global[j] {
                        jac[i * np + g] += dy[i * nth + j] * dtheta[j];
                    }
                }
                for (m, &(g, d)) in x0_chain.iter().enumerate() {
                    jac[i * np + g] += dy0[i * nx + m] * d;
                }
                if let Some(l) = filter.as_mut() {
                    l.apply(i, &mut eps[i], &mut jac[i * np..(i + 1) * np]);
                }
            }
            f(k, &eps, &w, &jac);
        };
        let options = SimOptions {
            horizon: self.horizon,
            x0: Some(&x0),
            x0_sensitivity: term.x0_free.is_some(),
            fd_scale: Some(&scale),
        };
        visit_sensitivities(self.model, &term.prep, &theta, &options, visit)
    }

    /// Cost `V(p)` and normal equations `JᵀWJ`, `JᵀWψ` in one pass per experiment
    /// (experiments in parallel, summed in a fixed order: identical for any thread count).
    ///
    /// # Errors
    /// Those of the simulation: invalid θ, [`Error::SimulationDiverged`].
    pub fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        let np = self.free.len();
        let parts: Vec<Result<Partial>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| {
                let mut cost = 0.0;
                let mut jtj = vec![0.0; np * np];
                let mut jtr = vec![0.0; np];
                self.pass(e, p, |_, eps, w, jac| {
                    for (i, (&ei, &wi)) in eps.iter().zip(w).enumerate() {
                        let (rho, psi, irls, _) = self.loss.eval(i, ei);
                        cost += wi * rho;
                        let row = &jac[i * np..(i + 1) * np];
                        for a in 0..np {
                            jtr[a] += wi * row[a] * psi;
                            let wa = wi * irls * row[a];
                            for b in a..np {
                                jtj[a * np + b] += wa * row[b];
                            }
                        }
                    }
                })?;
                Ok((cost, jtj, jtr))
            })
            .collect();
        let mut out = NormalEquations { cost: 0.0, jtj: DMatrix::zeros(np, np), jtr: DVector::zeros(np) };
        for part in parts {
            let (c, jtj, jtr) = part?;
            out.cost += c;
            for a in 0..np {
                out.jtr[a] += jtr[a];
                for b in a..np {
                    out.jtj[(a, b)] += jtj[a * np + b];
                }
            }
        }
        out.jtj.fill_lower_triangle_with_upper_triangle();
        Ok(out)
    }

    /// Cost `V(p)` only (simulation without sensitivities).
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn cost(&self, p: &DVector<f64>) -> Result<f64> {
        let ny = self.model.n_outputs();
        let parts: Vec<Result<f64>> = (0..self.terms.len())
            .into_par_iter()
            .map(|e| {
                let term = &self.terms[e];
                let x0 = self.x0(e, p);
                let options = SimOptions { horizon: self.horizon, x0: Some(&x0), ..Default::default() };
                let yhat = simulate(self.model, &term.prep, &self.theta(e, p), &options)?;
                let first = self.first_sample(e);
                let mut filter = self.prefilters.get(e).map(|l| ResidualFilter::new(l, ny, 0));
                let mut cost = 0.0;
                for k in first..term.prep.n {
                    let beta = term.weights.as_ref().map_or(1.0, |b| b[k]);
                    for i in 0..ny {
                        let mut eps = term.prep.y[k * ny + i] - yhat[k * ny + i];
                        if let Some(l) = filter.as_mut() {
                            l.apply(i, &mut eps, &mut []);
                        }
                        cost += beta * self.output_weights[i] * self.loss.eval(i, eps).0;
                    }
                }
                Ok(cost)
            })
            .collect();
        parts.into_iter().sum()
    }

    /// Weighted residuals `√w ε` stacked `[e][k][i]` and the Jacobian `√w ∂ŷ/∂p`
    /// (`N_total n_y × n_p`): the full matrices, for tests and diagnostics only
    /// (quadratic-loss view; the default path never forms them).
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn residuals_and_jacobian(&self, p: &DVector<f64>) -> Result<(DVector<f64>, DMatrix<f64>)> {
        let np = self.free.len();
        let mut r = Vec::new();
        let mut rows: Vec<f64> = Vec::new();
        for e in 0..self.terms.len() {
            self.pass(e, p, |_, eps, w, jac| {
                for i in 0..eps.len() {
                    let sw = w[i].sqrt();
                    r.push(sw * eps[i]);
                    rows.extend(jac[i * np..(i + 1) * np].iter().map(|v| sw * v));
                }
            })?;
        }
        let m = r.len();
        Ok((DVector::from_vec(r), DMatrix::from_row_slice(m, np, &rows)))
    }

    /// Sums for the statistics of a fit at p (one pass per experiment).
    ///
    /// # Errors
    /// As [`normal_equations`](Self::normal_equations).
    pub fn sums(&self, p: &DVector<f64>) -> Result<Sums> {
        let (ny, np) = (self.model.n_outputs(), self.free.len());
        let mut acc = Accumulator::new(ny, np);
        for e in 0..self.terms.len() {
            let term = &self.terms[e];
            // Shift by the first measurement to keep Σy² − (Σy)²/n free of cancellation.
            acc.start_experiment(term.prep.y_at(0, ny));
            match self.prefilters.get(e) {
                None => self.pass(e, p, |k, eps, w, jac| {
                    acc.sample(&self.loss, term.prep.y_at(k, ny), eps, eps, w, jac);
                    for i in 0..ny {
                        let psi = self.loss.eval(i, eps[i]).1;
                        let m = match self.loss {
                            Loss::Quadratic => w[i] * w[i],
                            Loss::Huber { .. } => w[i] * w[i] * psi * psi,
                        };
                        acc.add_meat(i, m, &jac[i * np..(i + 1) * np]);
                    }
                })?,
                Some(l) => {
                    // The criterion sees L(q)ε; under white raw residuals e the score is
                    // J_fᵀ W L e, whose covariance is σ² gᵀg with g = Lᵀ (W J_f): the
                    // time-reversed filter applied to the weighted filtered Jacobian.
                    let mut raw: Vec<RawSample> = Vec::new();
                    self.pass_with(e, p, false, |k, eps, w, jac| {
                        raw.push((k, eps.to_vec(), w.to_vec(), jac.to_vec()))
                    })?;
                    let sections = l.sections().len();
                    let mut filter = ResidualFilter::new(l, ny, np);
                    let mut weighted = vec![vec![0.0; raw.len()]; ny * np];
                    for (n, (k, eps, w, jac)) in raw.iter_mut().enumerate() {
                        let mut eps_f = eps.clone();
                        for i in 0..ny {
                            filter.apply(i, &mut eps_f[i], &mut jac[i * np..(i + 1) * np]);
                        }
                        acc.sample(&self.loss, term.prep.y_at(*k, ny), &eps_f, eps, w, jac);
                        for i in 0..ny {
                            let dpsi = self.loss.eval(i, eps_f[i]).3;
                            for a in 0..np {
                                weighted[i * np + a][n] = w[i] * dpsi * jac[i * np + a];
                            }
                        }
                    }
                    for i in 0..ny {
                        let g: Vec<Vec<f64>> = (0..np)
                            .map(|a| {
                                let mut z = vec![[0.0; 2]; sections];
                                let mut col: Vec<f64> =
                                    weighted[i * np + a].iter().rev().map(|&v| l.step(&mut z, v)).collect();
                                col.reverse();
                                col
                            })
                            .collect();
                        let mut row = vec![0.0; np];
                        for n in 0..raw.len() {
                            for (r, col) in row.iter_mut().zip(&g) {
                                *r = col[n];
                            }
                            acc.add_meat(i, 1.0, &row);
                        }
                    }
                }
            }
            acc.end_experiment();
        }
        Ok(acc.finish(&self.loss, !self.prefilters.is_empty()))
    }

    /// Robust scale `1.4826 × MAD` of each output's residuals at p (length n_y), the
    /// standard deviation for Gaussian residuals (Huber 1981, 5.1).
    ///
    /// # Errors
    /// As [`cost`](Self::cost).
    pub fn robust_scale(&self, p: &DVector<f64>) -> Result<Vec<f64>> {
        let ny = self.model.n_outputs();
        let mut res: Vec<Vec<f64>> = vec![Vec::new(); ny];
        for (e, term) in self.terms.iter().enumerate() {
            let x0 = self.x0(e, p);
            let options = SimOptions { horizon: self.horizon, x0: Some(&x0), ..Default::default() };
            let yhat = simulate(self.model, &term.prep, &self.theta(e, p), &options)?;
            for k in self.first_sample(e)..term.prep.n {
                for (i, r) in res.iter_mut().enumerate() {
                    r.push(term.prep.y[k * ny + i] - yhat[k * ny + i]);
                }
            }
        }
        Ok(res.into_iter().map(|r| 1.4826 * mad(r)).collect())
    }

    /// Gives the experiments' data back (to build a problem with other options).
    pub fn into_data(self) -> Vec<WeightedData<M::Inputs>> {
        self.terms.into_iter().map(|t| (t.prep, t.weights)).collect()
    }
}

/// Median absolute deviation from the median (0 for an empty slice).
fn mad(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let median = |v: &mut Vec<f64>| {
        let m = v.len() / 2;
        *v.select_nth_unstable_by(m, f64::total_cmp).1
    };
    let med = median(&mut v);
    for x in v.iter_mut() {
        *x = (*x - med).abs();
    }
    median(&mut v)
}

/// The residual prefilter L(q) run sample by sample over each output's residual and its
/// Jacobian row (one filter state per channel, from rest).
struct ResidualFilter<'f> {
    l: &'f Butterworth,
    eps: Vec<Vec<[f64; 2]>>,
    jac: Vec<Vec<[f64; 2]>>,
    np: usize,
}

impl<'f> ResidualFilter<'f> {
    /// States for `ny` residuals and `ny × np` Jacobian entries.
    fn new(l: &'f Butterworth, ny: usize, np: usize) -> Self {
        let sections = l.sections().len();
        Self { l, eps: vec![vec![[0.0; 2]; sections]; ny], jac: vec![vec![[0.0; 2]; sections]; ny * np], np }
    }

    /// Filters output i's residual and its Jacobian row (length n_p, or empty) in place.
    #[inline]
    fn apply(&mut self, i: usize, eps: &mut f64, row: &mut [f64]) {
        *eps = self.l.step(&mut self.eps[i], *eps);
        for (a, v) in row.iter_mut().enumerate() {
            *v = self.l.step(&mut self.jac[i * self.np + a], *v);
        }
    }
}

/// One unfiltered sample of a pass: `(k, ε, w, J)`.
type RawSample = (usize, Vec<f64>, Vec<f64>, Vec<f64>);

/// Running sums of [`PemProblem::sums`].
struct Accumulator {
    ny: usize,
    np: usize,
    cost: f64,
    e2w: f64,
    count: usize,
    n_e: usize,
    sse: Vec<f64>,
    // Raw residuals of samples with non-zero weight: the noise estimate ignores weighted-out ones.
    sse_live: Vec<f64>,
    n_live: Vec<usize>,
    y0: Vec<f64>,
    ey: Vec<f64>,
    ey2: Vec<f64>,
    sum_y: Vec<f64>,
    sum_y2: Vec<f64>,
    jtj: DMatrix<f64>,
    bread: DMatrix<f64>,
    // Per output: Σ w² J_iᵀJ_i (quadratic), Σ w² ψ² J_iᵀJ_i (Huber) or gᵀg (prefilter).
    meat_i: Vec<DMatrix<f64>>,
}

impl Accumulator {
    fn new(ny: usize, np: usize) -> Self {
        let z = DMatrix::zeros(np, np);
        Self {
            ny,
            np,
            cost: 0.0,
            e2w: 0.0,
            count: 0,
            n_e: 0,
            sse: vec![0.0; ny],
            sse_live: vec![0.0; ny],
            n_live: vec![0; ny],
            y0: vec![0.0; ny],
            ey: vec![0.0; ny],
            ey2: vec![0.0; ny],
            sum_y: vec![0.0; ny],
            sum_y2: vec![0.0; ny],
            jtj: z.clone(),
            bread: z.clone(),
            meat_i: vec![z; ny],
        }
    }

    fn start_experiment(&mut self, y0: &[f64]) {
        self.y0.copy_from_slice(y0);
        self.ey.fill(0.0);
        self.ey2.fill(0.0);
        self.n_e = 0;
    }

    /// One sample: `eps` the residual the criterion sees (filtered or not), `raw` the
    /// output error itself, `jac` the criterion's Jacobian (row-major n_y × n_p).
    fn sample(&mut self, loss: &Loss, y: &[f64], eps: &[f64], raw: &[f64], w: &[f64], jac: &[f64]) {
        let np = self.np;
        self.n_e += 1;
        for i in 0..self.ny {
            let (rho, _, _, dpsi) = loss.eval(i, eps[i]);
            self.cost += w[i] * rho;
            self.e2w += w[i] * eps[i] * eps[i];
            self.sse[i] += raw[i] * raw[i];
            if w[i] > 0.0 {
                self.sse_live[i] += raw[i] * raw[i];
                self.n_live[i] += 1;
            }
            let d = y[i] - self.y0[i];
            self.ey[i] += d;
            self.ey2[i] += d * d;
            let row = &jac[i * np..(i + 1) * np];
            for a in 0..np {
                for b in a..np {
                    let jj = row[a] * row[b];
                    self.jtj[(a, b)] += w[i] * jj;
                    self.bread[(a, b)] += w[i] * dpsi * jj;
                }
            }
        }
    }

    /// Adds `m · row rowᵀ` to the meat of output i (upper triangle).
    fn add_meat(&mut self, i: usize, m: f64, row: &[f64]) {
        for a in 0..self.np {
            for b in a..self.np {
                self.meat_i[i][(a, b)] += m * row[a] * row[b];
            }
        }
    }

    fn end_experiment(&mut self) {
        let n = self.n_e as f64;
        self.count += self.n_e;
        for i in 0..self.ny {
            // Pool about the grand mean over all experiments.
            let y0 = self.y0[i];
            self.sum_y[i] += self.ey[i] + n * y0;
            self.sum_y2[i] += self.ey2[i] + 2.0 * y0 * self.ey[i] + n * y0 * y0;
        }
    }

    fn finish(mut self, loss: &Loss, prefiltered: bool) -> Sums {
        let (ny, np, n) = (self.ny, self.np, self.count as f64);
        let sst = (0..ny).map(|i| (self.sum_y2[i] - self.sum_y[i] * self.sum_y[i] / n).max(0.0)).collect();
        let mut meat = DMatrix::zeros(np, np);
        for (i, mi) in self.meat_i.iter().enumerate() {
            let live = self.n_live[i] as f64;
            let dof = (live - np as f64 / ny as f64).max(1.0);
            let factor = match loss {
                // Huber without prefilter: ψ² is already in the meat.
                Loss::Huber { .. } if !prefiltered => live / dof,
                // σ̂_i² = E_i²/(N − n_p/n_y) of the raw residuals with non-zero weight.
                _ => self.sse_live[i] / dof,
            };
            meat += mi * factor;
        }
        for m in [&mut self.jtj, &mut self.bread, &mut meat] {
            m.fill_lower_triangle_with_upper_triangle();
        }
        Sums {
            cost: self.cost,
            e2_weighted: self.e2w,
            sse: self.sse,
            count: self.count,
            sst,
            jtj: self.jtj,
            bread: self.bread,
            meat,
        }
    }
}
