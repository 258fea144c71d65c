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

mod accumulate;
mod batches;
mod best;
mod build;
mod geodesic;
mod gram;
mod kept;
mod lags;
mod local;
mod loss;
mod map;
mod normal;
mod partition;
mod pass;
mod pem;
mod sums;

pub use crate::estimate::solver::NormalEquations;
pub use accumulate::Sums;
pub use batches::{BatchMeans, MIN_BATCHES, TARGET_BATCHES};
pub(crate) use batches::{BlockScores, ScoreSeries};
pub use build::OUTPUT_WEIGHT_RANGE;
#[cfg(test)]
pub(crate) use gram::dot;
#[cfg(test)]
pub(crate) use gram::lagged_dots;
pub(crate) use lags::LagStream;
pub use lags::{LAG_CHUNK, LagSums, WHITENESS_LAGS};
pub use loss::Loss;
pub(crate) use partition::partition;
pub use pem::{
    FreeKind, FreeParameter, PemProblem, ProblemOptions, STRUCTURED_ABOVE, Slot, Term, WeightedData,
};
pub use sums::ROOT_MAX_ENTRIES;
