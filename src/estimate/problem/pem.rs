//! The prediction-error problem's data ([`PemProblem`]): its experiments' terms, free
//! parameters and options. It is built in `build` and passed over in `pass`, `normal`, `sums`,
//! `best` and `map`.

use super::kept::BestPass;
use super::loss::Loss;
use crate::estimate::arrowhead::ArrowLayout;
use crate::estimate::filter::Butterworth;
use crate::estimate::scaling::Transform;
use crate::estimate::solver::NormalEquations;
use crate::model::{GreyBoxModel, Prepared};
use nalgebra::DVector;

/// One experiment's prepared data with optional per-sample weights β_k (length N).
pub type WeightedData<I> = (Prepared<I>, Option<Vec<f64>>);

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
    /// Free parameters above which `JᵀWJ` and the statistics are kept by arrowhead blocks;
    /// `None`: [`STRUCTURED_ABOVE`]. (`Some(usize::MAX)` keeps every problem dense, for
    /// comparisons.)
    pub structured_above: Option<usize>,
}

/// Where each model parameter of one experiment comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Slot {
    /// Held at this value \[parameter unit\].
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

/// A prediction-error problem over one or more experiments of one model.
pub struct PemProblem<'m, M: GreyBoxModel> {
    pub(super) model: &'m M,
    pub(super) terms: Vec<Term<M::Inputs>>,
    pub(super) free: Vec<FreeParameter>,
    pub(super) horizon: Option<usize>,
    pub(super) output_weights: Vec<f64>,
    pub(super) loss: Loss,
    pub(super) prefilters: Vec<Butterworth>,
    /// The normal-equation pass of lowest cost so far, for the statistics at the estimate.
    pub(super) best: BestPass,
    /// A normal-equation pass already made (at its point p), handed to the solver's first
    /// request at that very point instead of a second pass.
    pub(super) seed: std::sync::Mutex<Option<(DVector<f64>, NormalEquations)>>,
    /// The block-arrowhead layout of `JᵀWJ` (each free parameter shared or one
    /// experiment's), when the sums are kept by its blocks (more than
    /// [`STRUCTURED_ABOVE`] free parameters, no prefilter); `None`: dense.
    pub(super) layout: Option<std::sync::Arc<ArrowLayout>>,
}

/// Free parameters above which a problem keeps `JᵀWJ` and the statistics' sums by the
/// blocks of their arrowhead structure ([`crate::estimate::Arrowhead`]) and solves by the
/// Schur complement; at most this many, dense (and the same bits as before the structure
/// existed).
pub const STRUCTURED_ABOVE: usize = 64;

impl<'m, M: GreyBoxModel> PemProblem<'m, M> {
    /// The model.
    pub fn model(&self) -> &'m M {
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
    /// Number of free parameters n_free.
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
    /// The arrowhead layout of `JᵀWJ` when it is kept by blocks (see [`STRUCTURED_ABOVE`]).
    pub fn layout(&self) -> Option<&std::sync::Arc<ArrowLayout>> {
        self.layout.as_ref()
    }

    /// Gives the experiments' data back (to build a problem with other options).
    pub fn into_data(self) -> Vec<WeightedData<M::Inputs>> {
        self.terms.into_iter().map(|t| (t.prep, t.weights)).collect()
    }
}
