//! A check that needs no estimate, running beside a fit ([`super::fit_pmsm`]).

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
