//! Residual losses: quadratic, and Huber's (Huber 1981, *Robust Statistics*, 7.8); the
//! robust scale of the residuals that sets Huber's thresholds.

use super::PemProblem;
use super::pass::Pass;
use crate::error::Result;
use crate::model::GreyBoxModel;
use nalgebra::DVector;
use serde::{Deserialize, Serialize};

/// The loss ρ applied to each residual.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Loss {
    /// `ρ(ε) = ½ ε²`.
    #[default]
    Quadratic,
    /// Huber's loss with threshold δ_i per output \[output unit\], length n_y.
    Huber {
        /// Thresholds δ_i > 0.
        delta: Vec<f64>,
    },
}

impl Loss {
    /// `(ρ(ε), ψ(ε), IRLS weight ψ(ε)/ε, ψ'(ε))` for residual `e` of output `i`.
    #[inline]
    pub(crate) fn eval(&self, i: usize, e: f64) -> (f64, f64, f64, f64) {
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

impl<M: GreyBoxModel> PemProblem<'_, M> {
    /// Robust scale `1.4826 × MAD` of each output's residuals at p (length n_y), the
    /// standard deviation for Gaussian residuals (Huber 1981, 5.1).
    ///
    /// # Errors
    /// As [`cost`](Self::cost).
    pub fn robust_scale(&self, p: &DVector<f64>) -> Result<Vec<f64>> {
        let ny = self.model.n_outputs();
        let mut res: Vec<Vec<f64>> = vec![Vec::new(); ny];
        for e in 0..self.terms.len() {
            self.pass(e, p, Pass::RAW_RESIDUALS, |_, eps, _, _| {
                for (r, &v) in res.iter_mut().zip(eps) {
                    r.push(v);
                }
            })?;
        }
        Ok(res.into_iter().map(|r| 1.4826 * mad(r)).collect())
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
