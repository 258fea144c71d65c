//! The checks that need no estimate, running beside a fit ([`super::fit_pmsm`]).

use crate::estimate::result::Warning;
use nalgebra::DMatrix;
use std::thread::ScopedJoinHandle;

/// The checks running beside a fit (see [`super::fit_pmsm`]).
pub(super) struct Beside<'s> {
    pub scan: Pending<'s, Option<DMatrix<f64>>>,
    pub dead: Pending<'s, Vec<Option<Warning>>>,
}

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
