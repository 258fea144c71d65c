//! A log as the checks on the voltage equations read it, prepared once per fit.

use crate::error::Result;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::driving_voltage;
use crate::pmsm::options::PmsmFitOptions;
use std::borrow::Cow;

/// One log's dq view and the voltage that drives the model, `(u_d, u_q)` \[V\] of length
/// N: the terminal voltage borrowed, or the reference applied with the fit's delay and
/// advance. Built once per fit ([`prepare`]) and read by the dead-time and late-voltage
/// checks, which would otherwise each build it again. (The setup scan derives its own with
/// one pole pair: it compares pole-pair numbers.)
pub(crate) struct PreparedLog<'a> {
    /// The log's typed channels.
    pub view: DqView<'a>,
    /// The driving voltage's d component \[V\].
    pub u_d: Cow<'a, [f64]>,
    /// The driving voltage's q component \[V\].
    pub u_q: Cow<'a, [f64]>,
}

impl<'a> PreparedLog<'a> {
    /// The prepared log of the validated `view` for a fit with `options`.
    ///
    /// # Errors
    /// Those of the driving voltage (a missing channel).
    pub(crate) fn new(view: DqView<'a>, options: &PmsmFitOptions) -> Result<Self> {
        let (u_d, u_q) = driving_voltage(&view, options.pole_pairs, options.input)?;
        Ok(Self { view, u_d, u_q })
    }
}

/// Every log (`views`) prepared for a fit with `options`, in order; `None` for a log the checks
/// cannot read (they pass it over).
pub(crate) fn prepare<'a>(views: &[DqView<'a>], options: &PmsmFitOptions) -> Vec<Option<PreparedLog<'a>>> {
    views.iter().map(|&v| PreparedLog::new(v, options).ok()).collect()
}
