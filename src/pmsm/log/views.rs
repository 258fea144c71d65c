//! The logs of one fit, each validated once as a [`DqView`] where the fit starts and
//! passed down to its checks, starts and fits, which then read the typed channels without
//! validating them again.

use super::signals::DqView;
use crate::data::Experiment;
use crate::error::Result;

/// The logs of one fit and their validated dq views, in the same order: made once per fit
/// ([`DqLogs::try_new`]) and passed down.
///
/// A view borrows its log, so the logs as a slice (for the generic estimator, which takes
/// `&[Experiment]`) and the views (for the PMSM checks and starts, which read the dq
/// channels) travel together.
#[derive(Clone, Debug)]
pub(crate) struct DqLogs<'a> {
    experiments: &'a [Experiment],
    views: Vec<DqView<'a>>,
}

impl<'a> DqLogs<'a> {
    /// Validates every log of `experiments` once ([`DqView::try_new`]).
    ///
    /// # Errors
    /// The first log's error of [`DqView::try_new`]: [`crate::Error::MissingChannel`]
    /// naming the log and the channel it lacks, [`crate::Error::TooShort`] below
    /// [`super::signals::MIN_SAMPLES`] samples.
    pub(crate) fn try_new(experiments: &'a [Experiment]) -> Result<Self> {
        let views = experiments.iter().map(DqView::try_new).collect::<Result<Vec<_>>>()?;
        Ok(Self { experiments, views })
    }
    /// The logs (as many as [`views`](Self::views)).
    pub(crate) fn experiments(&self) -> &'a [Experiment] {
        self.experiments
    }
    /// The validated view of each log, in the logs' order.
    pub(crate) fn views(&self) -> &[DqView<'a>] {
        &self.views
    }
}

/// The longest sample time `max h` of the logs `views` \[s\] (0 for none).
pub(crate) fn longest_h(views: &[DqView<'_>]) -> f64 {
    views.iter().map(DqView::h).fold(0.0, f64::max)
}

/// Whether every log of `views` carries a modulator's reference `ud_ref, uq_ref`
/// ([`DqView::u_dq_ref`]): a modulator holds its output in the stator frame (MODEL.md §4).
pub(crate) fn modulator_reference(views: &[DqView<'_>]) -> bool {
    views.iter().all(|v| v.u_dq_ref().is_some())
}

/// The largest current magnitude `max |i_dq|` of the logs `views` \[A, peak\]
/// ([`DqView::peak_current`] of each; 0 for none).
pub(crate) fn peak_current(views: &[DqView<'_>]) -> f64 {
    views.iter().map(DqView::peak_current).fold(0.0, f64::max)
}
