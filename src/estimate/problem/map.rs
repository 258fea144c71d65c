//! The map between the optimiser's scaled vector p and each experiment's θ and initial
//! state: start point, values, bounds, and the chain factors `dθ/dp`.

use super::{FreeKind, PemProblem, Slot};
use crate::estimate::scaling::Transform;
use crate::estimate::solver::POSITIVE_FLOOR;
use crate::model::GreyBoxModel;
use nalgebra::DVector;

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// Scaled start vector p₀ (length n_free) for model start values θ₀ (initial states from
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

    /// Value of every free entry at p in its own unit (model parameters and initial
    /// states), length n_free: the fitted vector in a form independent of the scaling.
    pub fn free_values(&self, p: &DVector<f64>) -> Vec<f64> {
        self.free.iter().enumerate().map(|(g, f)| f.transform.to_theta(p[g])).collect()
    }

    /// The scaled point (projected onto the bounds) whose free entries take `values`
    /// ([`free_values`](Self::free_values) of a problem with the same layout).
    ///
    /// # Panics
    /// If `values` is shorter than n_free.
    pub fn point_from_values(&self, values: &[f64]) -> DVector<f64> {
        let mut p = DVector::from_iterator(
            self.free.len(),
            self.free.iter().zip(values).map(|(f, &v)| f.transform.to_scaled(v)),
        );
        self.project(&mut p);
        p
    }

    /// θ of experiment `e` at scaled point p (length n_free); returns length n_θ.
    ///
    /// # Panics
    /// If `e` is not an experiment index or p is shorter than n_free.
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

    /// [`LeastSquares::project_trial`](crate::estimate::solver::LeastSquares::project_trial):
    /// the clamp of [`project`](Self::project), where a step takes a linearly scaled model
    /// parameter with a lower bound above 0 past zero, that parameter put at
    /// a hundredth (`POSITIVE_FLOOR`) of its value at `from` first. Not a nuisance parameter: its
    /// bound may be its answer (a smooth function's width at its sharp limit; the gate's
    /// `nuisance_at_bound`), where a model parameter at its bound is untrusted.
    pub fn project_trial(&self, from: &DVector<f64>, p: &mut DVector<f64>) {
        let params = self.model.parameters();
        for (g, f) in self.free.iter().enumerate() {
            let model_parameter = matches!(f.kind, FreeKind::Parameter(j) if !params[j].nuisance);
            if model_parameter
                && matches!(f.transform, Transform::Linear { .. })
                && f.lower_p > 0.0
                && p[g] <= 0.0
            {
                p[g] = POSITIVE_FLOOR * from[g];
            }
        }
        self.project(p);
    }

    /// `dθ/dp` for every model parameter of experiment e, with its global index.
    pub(crate) fn chain(&self, e: usize, p: &DVector<f64>) -> (Vec<Option<usize>>, Vec<f64>) {
        self.terms[e]
            .slots
            .iter()
            .map(|s| match *s {
                Slot::Fixed(_) => (None, 0.0),
                Slot::Free(g) => (Some(g), self.free[g].transform.dtheta_dp(p[g])),
            })
            .unzip()
    }

    /// Each θ entry's finite-difference scale for experiment e: `|dθ/dp|` of a free
    /// parameter, `max(|θ|, 1e-12)` of a fixed one.
    pub(crate) fn fd_scale(&self, e: usize, p: &DVector<f64>) -> Vec<f64> {
        let theta = self.theta(e, p);
        let (_, d) = self.chain(e, p);
        d.iter().zip(&theta).map(|(&d, &t)| if d != 0.0 { d.abs() } else { t.abs().max(1e-12) }).collect()
    }
}
