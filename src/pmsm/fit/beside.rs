//! The checks that need no estimate, running beside a fit ([`crate::pmsm::fit_pmsm`]).

use crate::pmsm::checks::prepared::PreparedLog;
use std::thread::ScopedJoinHandle;

/// A check's result: on its way from a thread of its own, or at hand.
pub(super) enum Pending<'s, T> {
    Thread(ScopedJoinHandle<'s, T>),
    Ready(T),
}

impl<T> Pending<'_, T> {
    /// The result (a panic on the check's thread goes on here, as it would have inline).
    pub fn get(self) -> T {
        match self {
            Self::Thread(h) => h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)),
            Self::Ready(v) => v,
        }
    }
}

/// What the checks beside a fit ([`crate::pmsm::fit_pmsm`]) found without its estimate.
pub(super) struct Beside<'a> {
    /// The setup scan's regression Grams ([`crate::pmsm::checks::columns::scan`]); `None`
    /// when the setup checks are skipped or the scan cannot read a log.
    pub scan: Option<crate::pmsm::checks::columns::ColumnScan>,
    /// The logs prepared once for the checks on the voltage equations after the fit (the
    /// dead-time and late-voltage checks).
    pub logs: Vec<Option<PreparedLog<'a>>>,
    /// The delay check's screen of a PWM fit ([`crate::pmsm::checks::delay::screen`]): its
    /// averaged fits at three delays need no estimate of the PWM model.
    pub delay_screen: Option<bool>,
}
