//! The command line's spinner for solver runs: iteration and cost on stderr (hidden when
//! stderr is not a terminal), the [`ProgressObserver`] `greybox` installs at start.

use crate::estimate::solver::run::ProgressObserver;
use indicatif::{ProgressBar, ProgressDrawTarget};
use std::sync::Mutex;

/// One spinner at a time, made at a run's first iteration and cleared at its end.
#[derive(Default)]
pub struct Spinner {
    bar: Mutex<Option<ProgressBar>>,
}

impl ProgressObserver for Spinner {
    fn iteration(&self, iteration: u64, cost: f64) {
        let mut bar = self.bar.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let bar = bar.get_or_insert_with(|| {
            let b = ProgressBar::new_spinner();
            b.set_draw_target(ProgressDrawTarget::stderr());
            b
        });
        bar.set_message(format!("iteration {iteration}: cost {cost:.6e}"));
        bar.tick();
    }
    fn finished(&self) {
        let mut bar = self.bar.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(b) = bar.take() {
            b.finish_and_clear();
        }
    }
}
