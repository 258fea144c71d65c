//! Voltage limiting in a reference-voltage log (MODEL.md §8: `|u| ≤ U_dc/√3` for the
//! linear range of space-vector modulation). A reference beyond the limit was not applied
//! as logged, so the samples it drives are weighted out of the fit and counted in the
//! report.

use crate::data::Experiment;
use crate::error::Result;
use crate::estimate::Weighting;
use crate::pmsm::channel;
use crate::pmsm::model::interval::VoltageInput;

/// A weighting rule that zeroes the samples driven by a reference at or beyond `limit` and
/// keeps the `inner` rule's weights elsewhere.
#[derive(Debug)]
pub struct VoltageLimitWeighting<'a> {
    /// The rule for the other samples.
    pub inner: &'a dyn Weighting,
    /// Largest applicable voltage magnitude \[V\] (`U_dc/√3`).
    pub limit: f64,
    /// Delay of the reference \[samples\].
    pub delay: usize,
}

impl VoltageLimitWeighting<'_> {
    /// Whether sample k (the end of interval k − 1) is driven by a limited reference.
    fn limited(&self, e: &Experiment, k: usize) -> bool {
        let (Ok(ud), Ok(uq)) = (e.channel(channel::U_D_REF), e.channel(channel::U_Q_REF)) else {
            return false;
        };
        let Some(j) = k.checked_sub(1 + self.delay) else { return false };
        ud[j].hypot(uq[j]) >= (1.0 - 1e-3) * self.limit
    }

    /// Number of samples of `e` weighted out.
    pub fn count(&self, e: &Experiment) -> usize {
        (0..e.len()).filter(|&k| self.limited(e, k)).count()
    }
}

impl Weighting for VoltageLimitWeighting<'_> {
    fn name(&self) -> String {
        format!("{} without samples at the voltage limit {:.1} V", self.inner.name(), self.limit)
    }
    fn sample_weight(&self, e: &Experiment, k: usize) -> f64 {
        if self.limited(e, k) { 0.0 } else { self.inner.sample_weight(e, k) }
    }
    fn output_weights(&self) -> Option<Vec<f64>> {
        self.inner.output_weights()
    }
    fn check(&self, e: &Experiment) -> Result<()> {
        self.inner.check(e)
    }
}

/// The delay of a reference input, 0 for the terminal voltage.
pub(crate) fn delay_of(input: VoltageInput) -> usize {
    match input {
        VoltageInput::Reference { delay, .. } => delay,
        VoltageInput::Terminal => 0,
    }
}
