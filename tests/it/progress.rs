//! Progress reaches the caller's observer: the library shows nothing itself (issue 44).

use crate::mgh::{Mgh, driver_tolerances};
use greybox::estimate::{RunOptions, run_solver};
use nalgebra::DVector;

/// The solver shows nothing itself: a run with `progress` reports each iteration and its end
/// to the observer the caller installed (the command line's spinner), one without reports
/// nothing.
#[test]
fn progress_reaches_the_installed_observer_only() {
    use greybox::estimate::{ProgressObserver, set_progress_observer};
    use std::cell::Cell;
    // The observer is the process's: other tests' runs report to it too, each on its own
    // thread (a run calls it on the thread that runs the solver), so it counts per thread.
    thread_local! {
        static ITERATIONS: Cell<u64> = const { Cell::new(0) };
        static ENDS: Cell<u64> = const { Cell::new(0) };
    }
    struct Count;
    impl ProgressObserver for Count {
        fn iteration(&self, iteration: u64, cost: f64) {
            ITERATIONS.with(|n| {
                assert_eq!(iteration, n.get(), "the iterations in order, from 0");
                n.set(n.get() + 1);
            });
            assert!(cost.is_finite());
        }
        fn finished(&self) {
            ENDS.with(|n| n.set(n.get() + 1));
        }
    }
    assert!(set_progress_observer(Box::new(Count)), "no other test installs one");
    assert!(!set_progress_observer(Box::new(Count)), "once per process");
    let rosenbrock = crate::mgh_problems::problem(1, 2, 2);
    let problem = Mgh(rosenbrock.as_ref());
    let run = |progress: bool| {
        let options = RunOptions { tolerances: driver_tolerances(2), progress, ..Default::default() };
        run_solver(&problem, DVector::from_vec(rosenbrock.start_at(1.0)), &options).expect("the solver runs")
    };
    let (_, quiet) = run(false);
    assert!(quiet.iterations > 0);
    assert_eq!(ITERATIONS.with(Cell::get), 0, "a run without progress reports nothing");
    assert_eq!(ENDS.with(Cell::get), 0);
    let (_, shown) = run(true);
    assert_eq!(ITERATIONS.with(Cell::get), shown.iterations, "one report per iteration");
    assert!(ENDS.with(Cell::get) >= 1, "and its end");
}
