//! A fit's memory beyond its data is small: `fit_pmsm` on a 300 000-sample drive-simulator
//! log allocates at most a fifth of the data's size on top of it at its peak (issue 16:
//! peak memory ≤ 1.2× the data; O(n_θ²) beyond it), for either voltage hold and for the
//! automatic choice, and still lands on the plant's parameters.
//!
//! A target of its own because it replaces the global allocator: [`Tracking`] wraps
//! [`System`] and keeps the bytes live on every thread and their peak, so the fit's worker
//! threads are counted. Nothing else runs in this binary while the fit is measured (one
//! test).

use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{HoldChoice, PmsmFitOptions, fit_pmsm};
use greybox::{Channel, Experiment};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// [`System`], keeping the bytes live ([`LIVE`]) and their peak ([`PEAK`]).
struct Tracking;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grow(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::SeqCst) + bytes;
    PEAK.fetch_max(live, Ordering::SeqCst);
}

fn shrink(bytes: usize) {
    LIVE.fetch_sub(bytes, Ordering::SeqCst);
}

// SAFETY: every call is forwarded unchanged to `System`; the tracking touches no memory
// the allocator hands out.
unsafe impl GlobalAlloc for Tracking {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // Counted as the new block allocated before the old one is freed (the worst case).
        grow(new_size);
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            shrink(new_size);
        } else {
            shrink(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) };
        shrink(layout.size());
    }
}

#[global_allocator]
static GLOBAL: Tracking = Tracking;

/// Samples of the log.
const N: usize = 300_000;

#[test]
fn a_fit_allocates_at_most_a_fifth_of_its_data_beyond_it() {
    let base = scenario("exp3", SPM_MOTOR).unwrap();
    let cfg = DriveConfig { duration: (N - 1) as f64 * base.control.h, ..base };
    let log = simulate_drive(&cfg).unwrap();
    let truth = [log.truth.start.r_s, log.truth.start.l_d, log.truth.k_e];
    // The five channels the fit reads, shared with the simulator's log until it is dropped.
    let channels: Vec<Channel> =
        ["ud", "uq", "id", "iq", "w_m"].iter().map(|n| log.experiment.get(n).unwrap().clone()).collect();
    let e = Experiment::try_new("large", log.experiment.h(), channels).unwrap();
    drop(log);
    let data: usize = e.channels().iter().map(|c| c.values.len() * size_of::<f64>()).sum();
    assert_eq!(data, 5 * N * 8);
    for hold in [HoldChoice::Stator, HoldChoice::Dq, HoldChoice::Auto] {
        let before = LIVE.load(Ordering::SeqCst);
        PEAK.store(before, Ordering::SeqCst);
        let options = PmsmFitOptions { pole_pairs: SPM_MOTOR.n_p, hold, ..Default::default() };
        let fit = fit_pmsm(std::slice::from_ref(&e), &options).unwrap();
        let beyond = PEAK.load(Ordering::SeqCst) - before;
        println!(
            "{hold:?}: peak {beyond} bytes beyond the {data} of the data ({:.3})",
            beyond as f64 / data as f64
        );
        assert!(5 * beyond <= data, "{hold:?}: {beyond} bytes beyond the data's {data} at the peak");
        // The drive simulator's plant is the stator-held exact step: that hold lands on it.
        if hold != HoldChoice::Dq {
            for (name, t) in ["r_s", "l_s", "k_e"].iter().zip(truth) {
                let v = fit.parameter(name).unwrap().value;
                assert!((v / t - 1.0).abs() < 1e-6, "{hold:?}: {name} = {v}, plant {t}");
            }
        }
    }
}
