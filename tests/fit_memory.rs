//! A fit's memory beyond its data is small: `fit_pmsm` on a 300 000-sample drive-simulator
//! log of a surface-magnet machine (and a 40 000-sample one of an interior-magnet machine)
//! allocates at most a fifth of the data's size on top of it at its peak (issue 16: peak
//! memory ≤ 1.2× the data; O(n_θ²) beyond it), for either voltage hold and for the
//! automatic choice, and still lands on the plant's parameters.
//!
//! A target of its own because it replaces the global allocator: [`Tracking`] wraps
//! [`System`] and keeps the bytes live on every thread and their peak, so the fit's worker
//! threads are counted. Nothing else runs in this binary while the fit is measured (one
//! test).

use greybox::drive::{DriveConfig, IPM_MOTOR, SPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{HoldChoice, MotorKind, MotorParameters, PmsmFitOptions, fit_pmsm};
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

/// The drive simulator's exp3 moves on `motor` over `n` samples: the five channels a fit
/// reads as an experiment (the simulator's log dropped), the plant's `(r_s, l_d, l_q, k_e)`
/// and the data's size in bytes.
fn record(motor: MotorParameters, n: usize) -> (Experiment, [f64; 4], usize) {
    let base = scenario("exp3", motor).unwrap();
    let cfg = DriveConfig { duration: (n - 1) as f64 * base.control.h, ..base };
    let log = simulate_drive(&cfg).unwrap();
    let truth = [log.truth.start.r_s, log.truth.start.l_d, log.truth.start.l_q, log.truth.k_e];
    // The five channels the fit reads, shared with the simulator's log until it is dropped.
    let channels: Vec<Channel> =
        ["ud", "uq", "id", "iq", "w_m"].iter().map(|n| log.experiment.get(n).unwrap().clone()).collect();
    let e = Experiment::try_new("large", log.experiment.h(), channels).unwrap();
    drop(log);
    let data: usize = e.channels().iter().map(|c| c.values.len() * size_of::<f64>()).sum();
    assert_eq!(data, 5 * n * 8);
    (e, truth, data)
}

/// The peak bytes a fit of `e` allocates beyond what was live before it, and the fit's
/// estimates against the plant `truth` (checked for the holds that match the simulator's).
fn peak_beyond(e: &Experiment, truth: [f64; 4], model: MotorKind, n_p: u32, hold: HoldChoice) -> usize {
    let before = LIVE.load(Ordering::SeqCst);
    PEAK.store(before, Ordering::SeqCst);
    let options = PmsmFitOptions { model, hold, ..PmsmFitOptions::new(n_p) };
    let fit = fit_pmsm(std::slice::from_ref(e), &options).unwrap();
    let beyond = PEAK.load(Ordering::SeqCst) - before;
    // The drive simulator's plant is the stator-held exact step: that hold lands on it.
    if hold != HoldChoice::Dq {
        let (names, plant): (&[&str], Vec<f64>) = match model {
            MotorKind::Spm => (&["r_s", "l_s", "k_e"], vec![truth[0], truth[1], truth[3]]),
            MotorKind::Ipm => (&["r_s", "l_d", "l_q", "k_e"], truth.to_vec()),
        };
        for (name, t) in names.iter().zip(plant) {
            let v = fit.parameter(name).unwrap().value;
            assert!((v / t - 1.0).abs() < 1e-6, "{model:?} {hold:?}: {name} = {v}, plant {t}");
        }
    }
    beyond
}

/// At 300 000 samples a surface-magnet fit's peak beyond its data is at most a fifth of
/// the data; for both machines, doubling the record adds at most a twentieth of the added
/// data beyond it (the fit's own memory does not grow with N; a model that kept 40 bytes
/// a sample of its own would add all of it).
#[test]
fn a_fit_allocates_little_beyond_its_data_and_nothing_that_grows_with_it() {
    let cases = [(SPM_MOTOR, MotorKind::Spm, 150_000), (IPM_MOTOR, MotorKind::Ipm, 40_000)];
    for (motor, model, n) in cases {
        let (short, truth_short, data_short) = record(motor, n);
        let (long, truth_long, data_long) = record(motor, 2 * n);
        for hold in [HoldChoice::Stator, HoldChoice::Dq, HoldChoice::Auto] {
            let a = peak_beyond(&short, truth_short, model, motor.n_p, hold);
            let b = peak_beyond(&long, truth_long, model, motor.n_p, hold);
            println!(
                "{model:?} {hold:?}: peak {a} and {b} bytes beyond the {data_short} and {data_long} of the data"
            );
            let growth = b.saturating_sub(a);
            assert!(
                20 * growth <= data_long - data_short,
                "{model:?} {hold:?}: {growth} more bytes beyond the data for {} more of data",
                data_long - data_short
            );
            if model == MotorKind::Spm {
                assert!(5 * b <= data_long, "{model:?} {hold:?}: {b} bytes beyond the data's {data_long}");
            }
        }
    }
}
