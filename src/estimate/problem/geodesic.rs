//! What the geodesic acceleration of Levenberg-Marquardt
//! ([`crate::estimate::PemOptions::geodesic`]) needs from the prediction-error problem
//! ([`LeastSquares::directional_gradient`](crate::estimate::LeastSquares::directional_gradient)):
//! the residuals at a point `q` weighted by the Jacobian at `p`, `JᵀWε(q)`. It costs a
//! residual pass at `q` and a sensitivity pass at `p` (the Jacobian at `p` is not kept
//! between passes: n_samples × n_free), one experiment after another, and keeps one
//! experiment's residuals at `q` (n_samples × n_y) between the two: unlike the normal
//! equations, whose memory does not grow with the record and whose experiments run in
//! parallel. It is meant for curve fits, not for long records.

use super::PemProblem;
use super::local::Pass;
use super::loss::Loss;
use crate::error::Result;
use crate::model::GreyBoxModel;
use nalgebra::DVector;

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// `JᵀWε(q)` with `J = ∂ŷ/∂p` at `p` (length n_free): per experiment, a residual pass
    /// at `q` (kept, n_samples × n_y) and a sensitivity pass at `p` summing
    /// `J_kᵀ W_k ε_k(q)`, both as the criterion sees them (prefiltered where it is).
    /// `None` for the Huber loss, whose IRLS weights would differ between the points. At
    /// `q = p` it is [`normal_equations`](Self::normal_equations)'s `jtr` up to the order
    /// of summation.
    ///
    /// # Errors
    /// Those of the simulation at `p` or `q`: invalid θ, [`crate::Error::SimulationDiverged`].
    pub(crate) fn directional_gradient(
        &self,
        p: &DVector<f64>,
        q: &DVector<f64>,
    ) -> Result<Option<DVector<f64>>> {
        if !matches!(self.loss, Loss::Quadratic) {
            return Ok(None);
        }
        let (ny, np) = (self.model.n_outputs(), self.free.len());
        let mut g = DVector::zeros(np);
        let mut at_q = Vec::new();
        for e in 0..self.terms.len() {
            at_q.clear();
            self.pass(e, q, Pass::COST, |_, eps, _, _| at_q.extend_from_slice(eps))?;
            let mut k = 0;
            self.pass(e, p, Pass::CRITERION, |_, _, w, jac| {
                for i in 0..ny {
                    let we = w[i] * at_q[k * ny + i];
                    for (gj, jij) in g.iter_mut().zip(&jac[i * np..(i + 1) * np]) {
                        *gj += jij * we;
                    }
                }
                k += 1;
            })?;
        }
        Ok(Some(g))
    }
}
