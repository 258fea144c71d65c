//! What the core's tests share: a machine driven open loop by its own exact step.

use greybox_observer::{Complex, Plant, Sample};

/// `n` samples of `plant` (its true `k_e` \[V s/rad\], `r_s` \[Ω\]) driven open loop every
/// `h` \[s\]: the speed around 100 rad/s, the voltage the back-EMF plus a few volts at 5, 7
/// and 13 Hz about a d-axis offset `u_d0` \[V\] (so the d current passes the `R_s` law's
/// threshold), each current the exact step of the last.
///
/// # Panics
/// If a step fails (the tests' machines do not).
pub fn open_loop<P: Plant<f64>>(
    plant: &P,
    n: usize,
    h: f64,
    k_e: f64,
    r_s: f64,
    u_d0: f64,
) -> Vec<Sample<f64>>
where
    P::Error: core::fmt::Debug,
{
    let mut i = Complex::new(0.0, 0.0);
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 * h;
        let tau = std::f64::consts::TAU;
        let w_m = 100.0 + 20.0 * (tau * 2.0 * t).sin();
        let emf = greybox_observer::SQRT_2_3 * w_m * k_e;
        let u_d = u_d0 + 4.0 * (tau * 5.0 * t).sin() + (tau * 13.0 * t).sin();
        let u_q = emf + 3.0 + 2.0 * (tau * 7.0 * t).sin();
        let s = Sample { i_d: i.re, i_q: i.im, u_d, u_q, w_m };
        i = plant.step(i, k_e, r_s, &s, false).unwrap().next;
        out.push(s);
    }
    out
}
