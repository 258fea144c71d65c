//! Residual losses: quadratic, and Huber's (Huber 1981, *Robust Statistics*, 7.8); the
//! robust scale of the residuals that sets Huber's thresholds.

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
