//! The prediction-error problem: experiments, the map from the optimiser's scaled vector
//! p to each experiment's θ, and one-pass evaluation of the cost and normal equations.
//!
//! Criterion (MODEL.md §5; Ljung, *System Identification*, ch. 7):
//! `V(p) = ½ Σ_e Σ_k β_ek Σ_i Λ_i ε_eki²`, `ε = y − ŷ(θ(p))`. The Jacobian used is
//! `J = ∂ŷ/∂p` (so `∂ε/∂p = −J` and the Gauss-Newton step solves `JᵀWJ δ = JᵀWε`).

use crate::error::{Error, Result};
use crate::estimate::scaling::{ParameterScaling, Transform};
use crate::model::{GreyBoxModel, Prepared};
use crate::simulate::{Shooting, visit_sensitivities};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Where each model parameter of one experiment comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Slot {
    /// Held at this value [parameter unit].
    Fixed(f64),
    /// The optimiser's free parameter with this index.
    Free(usize),
}

/// One experiment's prepared data with optional per-sample weights β_k (length N).
pub type WeightedData<I> = (Prepared<I>, Option<Vec<f64>>);

/// One experiment's share of the cost and normal equations (cost, `JᵀWJ` row-major, `JᵀWε`).
type Partial = (f64, Vec<f64>, Vec<f64>);

/// One free parameter of the optimisation.
#[derive(Clone, Debug)]
pub struct FreeParameter {
    /// Model parameter index.
    pub index: usize,
    /// Experiment index for a per-experiment parameter; `None` when shared.
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
}

/// Cost and normal equations at one point (scaled space, length n_p).
#[derive(Clone, Debug)]
pub struct NormalEquations {
    /// `V = ½ Σ w ε²`.
    pub cost: f64,
    /// `JᵀWJ`, `n_p × n_p`.
    pub jtj: DMatrix<f64>,
    /// `JᵀWε`, length n_p.
    pub jtr: DVector<f64>,
}

/// Sums at the estimate from which the statistics of a fit follow.
#[derive(Clone, Debug)]
pub struct Sums {
    /// Weighted cost `½ Σ w ε²`.
    pub cost: f64,
    /// Unweighted residual sum of squares per output, length n_y.
    pub sse: Vec<f64>,
    /// Number of residual samples per output (same for every output).
    pub count: usize,
    /// `Σ (y − ȳ)²` per output, length n_y.
    pub sst: Vec<f64>,
    /// `JᵀWJ` (scaled space).
    pub jtj: DMatrix<f64>,
    /// Per output i: `Σ_k w_ki² J_kiᵀ J_ki` (scaled space), for the sandwich covariance.
    pub jtwwj: Vec<DMatrix<f64>>,
}

/// A prediction-error problem over one or more experiments of one model.
pub struct PemProblem<'m, M: GreyBoxModel> {
    model: &'m M,
    terms: Vec<Term<M::Inputs>>,
    free: Vec<FreeParameter>,
    shooting: Shooting,
    output_weights: Vec<f64>,
}

impl<'m, M: GreyBoxModel> PemProblem<'m, M> {
    /// Builds the problem: `start` (length n_θ) are the model parameters' start values,
    /// shared by all experiments; parameters named in `per_experiment` get one free copy
    /// per experiment; fixed parameters (metadata flag) are held at their start.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] for a wrong `start` length, an unknown name in
    /// `per_experiment`, wrong weight lengths or a non-positive output weight;
    /// [`Error::InvalidBounds`], [`Error::StartOutsideBounds`], [`Error::InvalidParameter`]
    /// for unusable bounds or starts; those of the scaling rule.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        model: &'m M,
        preps: Vec<WeightedData<M::Inputs>>,
        start: &[f64],
        per_experiment: &[String],
        scaling: &dyn ParameterScaling,
        shooting: Shooting,
        output_weights: Option<Vec<f64>>,
    ) -> Result<Self> {
        let params = model.parameters();
        if start.len() != params.len() {
            return Err(Error::InvalidOption {
                option: "start".into(),
                reason: format!(
                    "{} values given, model `{}` has {} parameters",
                    start.len(),
                    model.name(),
                    params.len()
                ),
            });
        }
        for name in per_experiment {
            if !params.iter().any(|p| &p.name == name) {
                return Err(Error::InvalidOption {
                    option: "per_experiment".into(),
                    reason: format!("no parameter `{name}` in model `{}`", model.name()),
                });
            }
        }
        for (p, &v) in params.iter().zip(start) {
            p.check_bounds()?;
            p.check_start(v)?;
        }
        let ny = model.n_outputs();
        let output_weights = output_weights.unwrap_or_else(|| vec![1.0; ny]);
        if output_weights.len() != ny || output_weights.iter().any(|w| !(w.is_finite() && *w > 0.0)) {
            return Err(Error::InvalidOption {
                option: "output_weights".into(),
                reason: format!("need {ny} positive finite weights, got {output_weights:?}"),
            });
        }
        let n_exp = preps.len();
        if n_exp == 0 {
            return Err(Error::InvalidOption {
                option: "experiments".into(),
                reason: "no experiment given".into(),
            });
        }
        let mut free = Vec::new();
        let mut slots = vec![vec![Slot::Fixed(0.0); params.len()]; n_exp];
        for (j, p) in params.iter().enumerate() {
            if p.fixed {
                for s in slots.iter_mut() {
                    s[j] = Slot::Fixed(start[j]);
                }
                continue;
            }
            let transform = scaling.transform(p, start[j], None)?;
            let (lower_p, upper_p) = (transform.to_scaled(p.lower), transform.to_scaled(p.upper));
            let copies: Vec<Option<usize>> =
                if per_experiment.contains(&p.name) { (0..n_exp).map(Some).collect() } else { vec![None] };
            for e in copies {
                let g = free.len();
                free.push(FreeParameter { index: j, experiment: e, transform, lower_p, upper_p });
                match e {
                    Some(e) => slots[e][j] = Slot::Free(g),
                    None => slots.iter_mut().for_each(|s| s[j] = Slot::Free(g)),
                }
            }
        }
        let mut terms = Vec::with_capacity(n_exp);
        for ((prep, weights), slots) in preps.into_iter().zip(slots) {
            if let Some(w) = &weights {
                if w.len() != prep.n {
                    return Err(Error::InvalidOption {
                        option: "weights".into(),
                        reason: format!(
                            "experiment `{}`: {} weights for {} samples",
                            prep.name,
                            w.len(),
                            prep.n
                        ),
                    });
                }
                if let Some((k, v)) = w.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v >= 0.0)) {
                    return Err(Error::InvalidOption {
                        option: "weights".into(),
                        reason: format!(
                            "experiment `{}`: weight {v} at sample {k} is not finite and ≥ 0",
                            prep.name
                        ),
                    });
                }
            }
            terms.push(Term { prep, weights, slots });
        }
        let mut problem = Self { model, terms, free, shooting, output_weights };
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
            // column norm in θ units: ‖∂ŷ/∂θ‖ = ‖∂ŷ/∂p‖ / (dθ/dp)
            let norm = ne.jtj[(g, g)].sqrt() / fp.transform.dtheta_dp(p0[g]).abs();
            let p = &params[fp.index];
            fp.transform = scaling.transform(p, start[fp.index], Some(norm))?;
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
    /// The shooting (simulation or k-step prediction).
    pub fn shooting(&self) -> Shooting {
        self.shooting
    }

    /// Scaled start vector p₀ for model start values θ₀.
    pub fn start_vector(&self, start: &[f64]) -> DVector<f64> {
        DVector::from_iterator(
            self.free.len(),
            self.free.iter().map(|f| f.transform.to_scaled(start[f.index])),
        )
    }

    /// θ of experiment `e` at scaled point p (length n_θ).
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

    /// Projects p onto the bounds (componentwise clamp in scaled space).
    pub fn project(&self, p: &mut DVector<f64>) {
        for (g, f) in self.free.iter().enumerate() {
            p[g] = p[g].clamp(f.lower_p, f.upper_p);
        }
    }

    /// `dθ/dp` for every model parameter of experiment e, with the global index (0 for fixed).
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
    fn pass<F>(&self, e: usize, p: &DVector<f64>, mut f: F) -> Result<()>
    where
        F: FnMut(usize, &[f64], &[f64], &[f64]),
    {
        let term = &self.terms[e];
        let (ny, np) = (self.model.n_outputs(), self.free.len());
        let theta = self.theta(e, p);
        let (global, dtheta) = self.chain(e, p);
        let scale = self.fd_scale(e, p);
        let mut eps = vec![0.0; ny];
        let mut jac = vec![0.0; ny * np];
        let mut w = vec![0.0; ny];
        let nth = theta.len();
        visit_sensitivities(self.model, &term.prep, &theta, &scale, self.shooting, |k, yhat, dy| {
            if !self.counted(k) {
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
            }
            f(k, &eps, &w, &jac);
        })
    }

    /// Whether sample k carries a residual: every sample but the first, whose prediction
    /// is the measured initial state itself.
    fn counted(&self, k: usize) -> bool {
        k > 0
    }

    /// Cost `V(p)` and normal equations `JᵀWJ`, `JᵀWε` in one pass per experiment
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
                        cost += 0.5 * wi * ei * ei;
                        let row = &jac[i * np..(i + 1) * np];
                        for a in 0..np {
                            let wa = wi * row[a];
                            jtr[a] += wa * ei;
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
        for a in 0..np {
            for b in 0..a {
                out.jtj[(a, b)] = out.jtj[(b, a)];
            }
        }
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
                let yhat =
                    crate::simulate::simulate_with(self.model, &term.prep, &self.theta(e, p), self.shooting)?;
                let mut cost = 0.0;
                for k in (0..term.prep.n).filter(|&k| self.counted(k)) {
                    let beta = term.weights.as_ref().map_or(1.0, |b| b[k]);
                    for i in 0..ny {
                        let eps = term.prep.y[k * ny + i] - yhat[k * ny + i];
                        cost += 0.5 * beta * self.output_weights[i] * eps * eps;
                    }
                }
                Ok(cost)
            })
            .collect();
        parts.into_iter().sum()
    }

    /// Weighted residuals `√w ε` stacked `[e][k][i]` and the Jacobian `√w ∂ŷ/∂p`
    /// (`N_total n_y × n_p`): the full matrices, for tests and diagnostics only.
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
        let mut s = Sums {
            cost: 0.0,
            sse: vec![0.0; ny],
            count: 0,
            sst: vec![0.0; ny],
            jtj: DMatrix::zeros(np, np),
            jtwwj: vec![DMatrix::zeros(np, np); ny],
        };
        let mut sum_y = vec![0.0; ny];
        let mut sum_y2 = vec![0.0; ny];
        for e in 0..self.terms.len() {
            let term = &self.terms[e];
            // Shift by the first measurement to keep Σy² − (Σy)²/n free of cancellation.
            let y0: Vec<f64> = term.prep.y_at(0, ny).to_vec();
            let (mut ey, mut ey2) = (vec![0.0; ny], vec![0.0; ny]);
            let mut count = 0usize;
            self.pass(e, p, |k, eps, w, jac| {
                count += 1;
                let y = term.prep.y_at(k, ny);
                for i in 0..ny {
                    s.cost += 0.5 * w[i] * eps[i] * eps[i];
                    s.sse[i] += eps[i] * eps[i];
                    let d = y[i] - y0[i];
                    ey[i] += d;
                    ey2[i] += d * d;
                    let row = &jac[i * np..(i + 1) * np];
                    for a in 0..np {
                        for b in 0..np {
                            s.jtj[(a, b)] += w[i] * row[a] * row[b];
                            s.jtwwj[i][(a, b)] += w[i] * w[i] * row[a] * row[b];
                        }
                    }
                }
            })?;
            s.count += count;
            for i in 0..ny {
                // Pool per-experiment means: Σ(y − ȳ)² over all experiments about the grand mean.
                sum_y[i] += ey[i] + count as f64 * y0[i];
                sum_y2[i] += ey2[i] + 2.0 * y0[i] * ey[i] + count as f64 * y0[i] * y0[i];
            }
        }
        for i in 0..ny {
            let n = s.count as f64;
            s.sst[i] = (sum_y2[i] - sum_y[i] * sum_y[i] / n).max(0.0);
        }
        Ok(s)
    }
}
