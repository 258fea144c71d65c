//! A known term subtracted from the criterion: bias-compensated least squares.
//!
//! When the data's noise enters a prediction through a noisy regressor (a one-step
//! predictor restarted from a measured state, errors in the variables), the least-squares
//! criterion's expectation carries a noise term that depends on θ, `E V(θ) = V₀(θ) + c(θ)`,
//! and its minimiser is biased. Subtracting a consistent estimate of `c(θ)` removes the bias
//! to first order in the noise variance (bias-compensated least squares: Stoica &
//! Söderström, *Int. J. Control* 35 (1982) 449–457; Söderström, *Automatica* 43 (2007)
//! 939–958, section 5). The model layer knows `c`; the solver only sees the corrected
//! cost `V − c` and gradient `∇V − ∇c` (the Gauss-Newton matrix `JᵀWJ` is kept: `∇²c` is of
//! the order of the noise variance). The trust gate's stationarity test takes the same
//! gradient, and the reported standard errors are the larger of the white and the
//! batch-means ones. A [`crate::estimate::Weighting`] carries the
//! correction ([`crate::estimate::Weighting::criterion_correction`]).

use crate::error::Result;
use crate::estimate::problem::{PemProblem, Slot};
use crate::estimate::solver::{LeastSquares, NormalEquations};
use crate::model::GreyBoxModel;
use nalgebra::DVector;

/// The term `c_e(θ)` a fit subtracts from its criterion, per experiment.
pub trait CriterionCorrection: Send + Sync + std::fmt::Debug {
    /// The term of experiment `experiment` (its index among the fit's experiments) at that
    /// experiment's θ (length n_θ, model order), in the units of the cost, and its gradient
    /// `∂c/∂θ` (length n_θ).
    ///
    /// # Errors
    /// [`crate::Error::InvalidParameter`] at a θ where the term is not defined (the solver
    /// treats it as an infinite cost at a trial point).
    fn term(&self, experiment: usize, theta: &[f64]) -> Result<(f64, Vec<f64>)>;

    /// [`term`](Self::term)'s value alone (a trial point's cost), the same number; by
    /// default `term`'s, for a term whose gradient costs little beside it.
    ///
    /// # Errors
    /// As [`term`](Self::term).
    fn value(&self, experiment: usize, theta: &[f64]) -> Result<f64> {
        Ok(self.term(experiment, theta)?.0)
    }
}

/// A prediction-error problem whose criterion is `V − Σ_e c_e`.
pub(crate) struct Compensated<'a, 'm, M: GreyBoxModel> {
    pub problem: &'a PemProblem<'m, M>,
    pub correction: &'a dyn CriterionCorrection,
}

impl<M: GreyBoxModel> Compensated<'_, '_, M> {
    /// `Σ_e c_e` at p and its gradient in the scaled space (length n_free), chained through
    /// each experiment's slots and the free parameters' `dθ/dp`.
    pub(crate) fn correction(&self, p: &DVector<f64>) -> Result<(f64, DVector<f64>)> {
        let free = self.problem.free();
        let mut grad = DVector::zeros(free.len());
        let mut total = 0.0;
        for (e, term) in self.problem.terms().iter().enumerate() {
            let (c, g) = self.correction.term(e, &self.problem.theta(e, p))?;
            total += c;
            for (slot, dc) in term.slots.iter().zip(&g) {
                if let Slot::Free(j) = *slot {
                    grad[j] += dc * free[j].transform.dtheta_dp(p[j]);
                }
            }
        }
        Ok((total, grad))
    }
    fn corrected(&self, p: &DVector<f64>, mut ne: NormalEquations) -> Result<NormalEquations> {
        let (c, grad) = self.correction(p)?;
        ne.cost -= c;
        // `jtr` is −∇V; the corrected gradient is ∇V − ∇c.
        ne.jtr += grad;
        Ok(ne)
    }
}

impl<M: GreyBoxModel> LeastSquares for Compensated<'_, '_, M> {
    fn n_params(&self) -> usize {
        self.problem.n_params()
    }
    fn normal_equations(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        self.corrected(p, self.problem.normal_equations(p)?)
    }
    fn normal_equations_likely_last(&self, p: &DVector<f64>) -> Result<NormalEquations> {
        self.corrected(p, self.problem.normal_equations_likely_last(p)?)
    }
    fn cost(&self, p: &DVector<f64>) -> Result<f64> {
        let mut total = 0.0;
        for e in 0..self.problem.terms().len() {
            total += self.correction.value(e, &self.problem.theta(e, p))?;
        }
        Ok(self.problem.cost(p)? - total)
    }
    fn project(&self, p: &mut DVector<f64>) {
        self.problem.project(p)
    }
    fn project_trial(&self, from: &DVector<f64>, p: &mut DVector<f64>) {
        self.problem.project_trial(from, p)
    }
}

/// The covariance with `b`'s correlations and, per parameter, the larger of `b`'s and `w`'s
/// standard errors (both `n × n`, symmetric positive semi-definite; so is the result,
/// `D R D` with `R` a correlation matrix). A compensated fit reports it in place of the
/// batch means `b` (white `w`): on noisy PWM logs the batch-means errors of `l_s`, `t_d`,
/// `u_th` were 0.2–1.0 times the white ones, while the estimates' spread over 14 noise
/// seeds matched the white ones (spread/error 0.96–1.06; |z| ≤ 2.3, against up to 5.3 with
/// the batch means); `r_s`'s and `k_e`'s white errors were 2.5 times their spread.
pub(crate) fn larger_errors(
    b: &nalgebra::DMatrix<f64>,
    w: &nalgebra::DMatrix<f64>,
) -> nalgebra::DMatrix<f64> {
    let n = b.nrows();
    let sb: Vec<f64> = (0..n).map(|i| b[(i, i)].max(0.0).sqrt()).collect();
    let d: Vec<f64> = (0..n).map(|i| sb[i].max(w[(i, i)].max(0.0).sqrt())).collect();
    nalgebra::DMatrix::from_fn(n, n, |i, j| {
        if sb[i] > 0.0 && sb[j] > 0.0 { b[(i, j)] / (sb[i] * sb[j]) * d[i] * d[j] } else { b[(i, j)] }
    })
}
