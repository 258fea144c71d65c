//! What every simulation shares: its options ([`SimOptions`]) and the checks of its
//! inputs, horizon and divergence.

use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Prepared, describe};

/// How a simulation runs: restarts, initial state, sensitivities. Plain data with
/// defaults (pure simulation from the measured first state).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SimOptions<'a> {
    /// Restart period in samples: `None` simulates the whole record (output error);
    /// `Some(k)` restarts the state from the measured output every k samples (k-step-ahead
    /// prediction; `k = 1` is one-step-ahead prediction, i.e. equation error). Restarting
    /// needs a model whose state is its output (`n_x = n_y`).
    pub horizon: Option<usize>,
    /// Initial state (length n_x); `None` = the measured one ([`Prepared::x0`]).
    pub x0: Option<&'a [f64]>,
    /// Also give `∂ŷ_k/∂x₀` to [`visit_sensitivities`](super::visit_sensitivities)'s closure.
    pub x0_sensitivity: bool,
    /// Each parameter's scale (length n_θ, positive): sets the finite-difference step
    /// (`∛ε × scale`) for models without analytic sensitivities; `None` = `|θ|` (1 where θ = 0).
    pub fd_scale: Option<&'a [f64]>,
}

impl SimOptions<'_> {
    /// Whether the state is reset to the measurement after the output at sample k.
    pub(crate) fn restarts_at(&self, k: usize) -> bool {
        matches!(self.horizon, Some(h) if k.is_multiple_of(h))
    }
}

/// Checks the shapes a model and its prepared data must agree on, so that a wrong θ or a
/// user model's inconsistent `prepare` gives an error instead of an index panic.
pub(crate) fn check_inputs<M: GreyBoxModel>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    x0: &[f64],
) -> Result<()> {
    let bad = |option: &str, reason: String| Err(Error::InvalidOption { option: option.into(), reason });
    let (nx, ny, nth) = (model.n_states(), model.n_outputs(), model.parameters().len());
    if theta.len() != nth {
        return bad(
            "theta",
            format!("{} values for model `{}` with {nth} parameters", theta.len(), model.name()),
        );
    }
    if x0.len() != nx {
        return bad("x0", format!("{} values for model `{}` with {nx} states", x0.len(), model.name()));
    }
    let min = if nx > 0 { 2 } else { 1 };
    if prep.n < min || prep.y.len() != ny || prep.y.iter().any(|c| c.len() != prep.n) {
        let lengths: Vec<usize> = prep.y.iter().map(|c| c.len()).collect();
        return bad(
            "prepared data",
            format!(
                "experiment `{}`: output columns of lengths {lengths:?} for {} samples of {ny} outputs (need N ≥ {min})",
                prep.name, prep.n
            ),
        );
    }
    if prep.x0.len() != nx {
        return bad(
            "prepared data",
            format!(
                "experiment `{}`: initial state of length {}, model has {nx} states",
                prep.name,
                prep.x0.len()
            ),
        );
    }
    Ok(())
}

pub(crate) fn check_shooting<M: GreyBoxModel>(model: &M, horizon: Option<usize>) -> Result<()> {
    match horizon {
        Some(0) => {
            Err(Error::InvalidOption { option: "horizon".into(), reason: "must be at least 1".into() })
        }
        Some(_) if model.n_states() != model.n_outputs() => Err(Error::InvalidOption {
            option: "horizon".into(),
            reason: format!(
                "model `{}` has {} states but {} outputs: restarting from measurements needs state = output",
                model.name(),
                model.n_states(),
                model.n_outputs()
            ),
        }),
        _ => Ok(()),
    }
}

pub(crate) fn diverged<M: GreyBoxModel>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
    k: usize,
) -> Error {
    Error::SimulationDiverged {
        experiment: prep.name.clone(),
        sample: k,
        parameters: describe(model.parameters(), theta),
    }
}
