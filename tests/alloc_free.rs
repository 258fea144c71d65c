//! The online estimators allocate nothing per sample: [`Mras::update`], [`Kalman::update`], and
//! [`Mras::compute_output`] with [`Mras::advance`], counted by a global allocator, for the
//! surface-magnet observer and the salient one (`l_q` given: the augmented exponential of
//! `greybox::pmsm::ExactPlant` with its sensitivities).
//!
//! A target of its own because it replaces the global allocator: [`Counting`] wraps
//! [`System`] and counts the allocations (`alloc`, `alloc_zeroed`, `realloc`) made on a
//! thread while that thread's flag is set, so the test harness and other threads (other
//! tests, should this file gain some) are not counted.
//!
//! Errors are the exception: [`Error::NonFinite`](greybox::Error::NonFinite) carries the
//! column's name as a `String`, so a non-finite sample may allocate; only the valid samples
//! are counted, and the non-finite ones are checked to return an error and leave the
//! observer unchanged.

use greybox::online::{Adaptation, Kalman, KalmanNoise, Mras, MrasConfig, Sample};
use greybox::pmsm::{C64, ExactPlant, MotorParameters, VoltageHold};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::f64::consts::TAU;
use std::sync::atomic::{AtomicUsize, Ordering};

/// [`System`], counting the allocations of threads whose [`COUNTING`] flag is set.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    // Const-initialised and without destructor: reading it never allocates.
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

fn count() {
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

// SAFETY: every call is forwarded unchanged to `System`; the counting touches no memory
// the allocator hands out.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// `f()` and the number of allocations this thread made while it ran.
fn allocations<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    COUNTING.set(true);
    let r = f();
    COUNTING.set(false);
    (r, ALLOCATIONS.load(Ordering::Relaxed) - before)
}

/// Observer updates per law and per API.
const UPDATES: usize = 100_000;
/// Sample time h [s].
const H: f64 = 1e-4;

/// `L_q` [H] of the salient observer and its samples (`L_d` = 4.5 mH).
const L_Q: f64 = 9e-3;

/// Sample k of an SPM (n_p = 4, L_s = 4.5 mH, R_s = 0.9 Ω, K_e = 0.54 V s/rad), or of a
/// salient machine with `L_d = 4.5 mH`, `L_q` = [`L_Q`], from its voltage equations
/// (MODEL.md §2) with a speed that reverses, `ω_m = 200 sin(2π 2 t)` rad/s (mechanical;
/// both signs for the relay), `i_q = 5 + sin(2π 11 t)` A and `i_d = 2 sin(2π 5 t)` A (above
/// and below the 0.5 A threshold of the `R_s` law, both signs).
fn sample_of(salient: bool, k: usize) -> Sample {
    let (n_p, l_d, r_s, k_e) = (4.0, 4.5e-3, 0.9, 0.54);
    let l_q = if salient { L_Q } else { l_d };
    let t = k as f64 * H;
    let w_m = 200.0 * (TAU * 2.0 * t).sin();
    let w_e = n_p * w_m;
    let (i_d, di_d) = (2.0 * (TAU * 5.0 * t).sin(), 2.0 * TAU * 5.0 * (TAU * 5.0 * t).cos());
    let (i_q, di_q) = (5.0 + (TAU * 11.0 * t).sin(), TAU * 11.0 * (TAU * 11.0 * t).cos());
    Sample {
        i_d,
        i_q,
        u_d: r_s * i_d + l_d * di_d - w_e * l_q * i_q,
        u_q: r_s * i_q + l_q * di_q + w_e * l_d * i_d + (2.0f64 / 3.0).sqrt() * w_m * k_e,
        w_m,
    }
}

/// Sample k with every 997th made non-finite in one of its five fields in turn.
fn sample_with_gaps(salient: bool, k: usize) -> Sample {
    let mut s = sample_of(salient, k);
    if k.is_multiple_of(997) {
        let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][k / 997 % 3];
        *[&mut s.i_d, &mut s.i_q, &mut s.u_d, &mut s.u_q, &mut s.w_m][k / 997 % 5] = bad;
    }
    s
}

fn is_finite(s: &Sample) -> bool {
    [s.i_d, s.i_q, s.u_d, s.u_q, s.w_m].iter().all(|v| v.is_finite())
}

fn observer(salient: bool, adaptation: Adaptation) -> Mras {
    let gamma_ke = if adaptation == Adaptation::Relay { 0.2 } else { 0.001 };
    let cfg = MrasConfig {
        n_p: 4,
        l_s: 4.5e-3,
        l_q: salient.then_some(L_Q),
        h: H,
        adaptation,
        gamma_ke,
        k_e0: 0.5,
        r_s0: 1.1,
        ..Default::default()
    };
    let mut m = Mras::try_new(cfg).unwrap();
    let sample = |k| sample_of(salient, k);
    // Warm-up: the first sample starts the observer, the next ones run the full path.
    for k in 0..10 {
        m.update(&sample(k)).unwrap();
    }
    m
}

// One test only: the counter is per thread, but a single test keeps the output plain.
#[test]
fn mras_allocates_nothing_per_sample() {
    // The counter sees an allocation on this thread (else a zero below would prove nothing).
    let (v, n) = allocations(|| std::hint::black_box(Vec::<u8>::with_capacity(8)));
    assert_eq!((v.capacity(), n), (8, 1));
    // The drive simulator's salient plant: ExactPlant::step and step_derivatives (the series
    // the observers' greybox_observer::Ipm steps with, checked below through the salient
    // observers) allocate nothing after construction (either hold).
    for hold in [VoltageHold::Stator, VoltageHold::Dq] {
        let mut plant = ExactPlant::new(4, H, true, hold).unwrap();
        let p = MotorParameters { r_s: 0.9, l_d: 4.5e-3, l_q: L_Q, psi_f: 0.11, n_p: 4 };
        let (acc, n) = allocations(|| {
            let mut acc = 0.0;
            for k in 0..UPDATES / 10 {
                let s = sample_of(true, k);
                let u0 = C64::new(s.u_d, s.u_q);
                acc += plant.step(&p, [s.i_d, s.i_q], u0, s.w_m).unwrap()[0];
                acc += plant.step_derivatives(&p, [s.i_d, s.i_q], u0, s.w_m).unwrap().d_r_s[1];
            }
            acc
        });
        assert!(acc.is_finite());
        assert_eq!(n, 0, "ExactPlant ({hold} hold) allocated {n} times");
    }
    for (salient, adaptation) in [
        (false, Adaptation::Lyapunov),
        (false, Adaptation::Relay),
        (true, Adaptation::Lyapunov),
        (true, Adaptation::Relay),
    ] {
        let sample = |k| sample_of(salient, k);
        let observer = |adaptation| observer(salient, adaptation);
        let sample_with_gaps = |k| sample_with_gaps(salient, k);
        let tag = if salient { "salient" } else { "surface" };
        // update over valid samples, in one counted window.
        let mut m = observer(adaptation);
        let start = std::time::Instant::now();
        let (active, n) = allocations(|| {
            let mut active = 0usize;
            for k in 10..10 + UPDATES {
                let est = m.update(&sample(k)).unwrap();
                active += usize::from(est.r_s_active);
            }
            active
        });
        let ns = start.elapsed().as_secs_f64() * 1e9 / UPDATES as f64;
        eprintln!("{tag} {adaptation:?}: {ns:.0} ns per update (quick timing, not asserted)");
        assert_eq!(n, 0, "{tag} {adaptation:?}: update allocated {n} times over {UPDATES} samples");
        assert!(active > UPDATES / 4, "{tag} {adaptation:?}: R_s law active at {active} samples only");
        let last = m.output();
        assert!(last.k_e.is_finite() && last.r_s.is_finite(), "{tag} {adaptation:?}: {last:?}");

        // compute_output + advance, likewise.
        let mut m = observer(adaptation);
        let ((), n) = allocations(|| {
            for k in 10..10 + UPDATES {
                let out = m.compute_output(&sample(k)).unwrap();
                m.advance(&out).unwrap();
            }
        });
        assert_eq!(n, 0, "{tag} {adaptation:?}: compute_output + advance allocated {n} times");

        // update with non-finite samples among the valid ones: only the valid ones counted.
        let mut m = observer(adaptation);
        let (mut valid_allocs, mut errors, mut error_allocs) = (0, 0, 0);
        for k in 10..10 + UPDATES {
            let s = sample_with_gaps(k);
            if is_finite(&s) {
                let (r, n) = allocations(|| m.update(&s).map(|_| ()));
                r.unwrap();
                valid_allocs += n;
            } else {
                let before = (m.output(), m.predicted_current());
                let (r, n) = allocations(|| m.update(&s).map(|_| ()));
                assert!(r.is_err(), "{tag} {adaptation:?}: sample {k} {s:?} accepted");
                assert_eq!((m.output(), m.predicted_current()), before, "sample {k} moved the observer");
                errors += 1;
                error_allocs += n;
            }
        }
        assert_eq!(
            valid_allocs, 0,
            "{tag} {adaptation:?}: update allocated {valid_allocs} times between errors"
        );
        assert!(errors > 90, "{errors} non-finite samples");
        // The errors' allocations (the column name of Error::NonFinite) are allowed.
        eprintln!(
            "{tag} {adaptation:?}: {errors} non-finite samples, {error_allocs} allocations in their errors"
        );
    }
    // The Kalman filter (issue 46): update allocates nothing either.
    for salient in [false, true] {
        let tag = if salient { "salient" } else { "surface" };
        let cfg = MrasConfig {
            n_p: 4,
            l_s: 4.5e-3,
            l_q: salient.then_some(L_Q),
            h: H,
            k_e0: 0.5,
            r_s0: 1.1,
            ..Default::default()
        };
        let mut filter = Kalman::try_new(cfg, KalmanNoise::for_machine(0.01, 1.1, 0.5)).unwrap();
        for k in 0..10 {
            filter.update(&sample_of(salient, k)).unwrap();
        }
        let start = std::time::Instant::now();
        let (se, n) = allocations(|| {
            let mut se = 0.0;
            for k in 10..10 + UPDATES {
                se = filter.update(&sample_of(salient, k)).unwrap().r_s_se;
            }
            se
        });
        let ns = start.elapsed().as_secs_f64() * 1e9 / UPDATES as f64;
        eprintln!("{tag} Kalman filter: {ns:.0} ns per update (quick timing, not asserted)");
        assert_eq!(n, 0, "{tag} Kalman filter: update allocated {n} times over {UPDATES} samples");
        assert!(se.is_finite() && se > 0.0, "{tag} Kalman filter: R_s standard error {se}");
    }
}
