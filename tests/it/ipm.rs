//! Exactness of the IPM step: against a fine RK4 integration of the continuous model,
//! against the SPM closed form at `L_d = L_q`, and its sensitivities against central
//! finite differences of a whole simulation.

use crate::common::{Signals, experiment};
use greybox::model::{GreyBoxModel, Prepared};
use greybox::pmsm::{DqView, PmsmIpm, PmsmSpm, VoltageHold};
use greybox::{Error, Experiment};

const H: f64 = 2e-4;
const N_P: u32 = 2;
const SQRT_2_3: f64 = 0.816_496_580_927_726;
/// `(r_s [Ω], l_d [H], l_q [H], k_e [V s/rad])`.
const THETA: [f64; 4] = [0.35, 3.2e-3, 7.5e-3, 0.4164];
const HOLDS: [VoltageHold; 2] = [VoltageHold::Dq, VoltageHold::Stator];

/// Period mean of `u₀ e^{−jω s}` over `[0, h)`: `u₀ (1 − e^{−jφ})/(jφ)`, written out
/// independently of the library's inverse.
fn stator_mean(u0: [f64; 2], phi: f64) -> [f64; 2] {
    // (1 − e^{−jφ})/(jφ) = sin φ/φ − j (1 − cos φ)/φ
    let (re, im) = if phi.abs() < 1e-4 {
        (1.0 - phi * phi / 6.0, -0.5 * phi + phi * phi * phi / 24.0)
    } else {
        (phi.sin() / phi, -(1.0 - phi.cos()) / phi)
    };
    [u0[0] * re - u0[1] * im, u0[0] * im + u0[1] * re]
}

/// Fine RK4 of the continuous IPM model over one period with interval-mean speed `w_m`
/// [rad/s mech] and start voltage `u0` (rotating backwards at ω_e for the stator hold).
fn rk4_period(th: [f64; 4], hold: VoltageHold, w_m: f64, u0: [f64; 2], x: [f64; 2], n: usize) -> [f64; 2] {
    let [r, l_d, l_q, k_e] = th;
    let w = f64::from(N_P) * w_m;
    let e = SQRT_2_3 * k_e * w_m;
    let v = |s: f64| match hold {
        VoltageHold::Dq => u0,
        VoltageHold::Stator => {
            let (sn, cs) = (w * s).sin_cos();
            [u0[0] * cs + u0[1] * sn, u0[1] * cs - u0[0] * sn]
        }
    };
    let f = |s: f64, x: [f64; 2]| {
        let v = v(s);
        [(v[0] - r * x[0] + w * l_q * x[1]) / l_d, (v[1] - r * x[1] - w * l_d * x[0] - e) / l_q]
    };
    let tau = H / n as f64;
    let mut x = x;
    for i in 0..n {
        let s = i as f64 * tau;
        let k1 = f(s, x);
        let k2 = f(s + 0.5 * tau, [x[0] + 0.5 * tau * k1[0], x[1] + 0.5 * tau * k1[1]]);
        let k3 = f(s + 0.5 * tau, [x[0] + 0.5 * tau * k2[0], x[1] + 0.5 * tau * k2[1]]);
        let k4 = f(s + tau, [x[0] + tau * k3[0], x[1] + tau * k3[1]]);
        for j in 0..2 {
            x[j] += tau / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
        }
    }
    x
}

/// A log of `n` samples: speed `w_m(k)` [rad/s mech], start-of-period voltages around the
/// steady state of a wandering current target plus pseudo-random steps, and currents from
/// RK4 with `rk4_n` substeps per period. Returns the experiment and the RK4 currents.
fn trajectory(
    hold: VoltageHold,
    n: usize,
    w_m: impl Fn(usize) -> f64,
    rk4_n: usize,
) -> (Experiment, Vec<[f64; 2]>) {
    let [r, l_d, l_q, k_e] = THETA;
    let psi_f = SQRT_2_3 * k_e / f64::from(N_P);
    let wm: Vec<f64> = (0..n).map(&w_m).collect();
    let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
    let mut noise = move || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut x = vec![[-4.0, 9.0]];
    let (mut u_d, mut u_q) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..n {
        let t = k as f64 * H;
        let wmk = if k + 1 < n { 0.5 * (wm[k] + wm[k + 1]) } else { wm[k] };
        let w = f64::from(N_P) * wmk;
        let (id, iq) = (-5.0 + 3.0 * (40.0 * t).sin(), 10.0 * (25.0 * t).cos());
        let u0 = [r * id - w * l_q * iq + 8.0 * noise(), r * iq + w * (l_d * id + psi_f) + 8.0 * noise()];
        let u = match hold {
            VoltageHold::Dq => u0,
            VoltageHold::Stator => stator_mean(u0, w * H),
        };
        u_d.push(u[0]);
        u_q.push(u[1]);
        if k + 1 < n {
            let xn = rk4_period(THETA, hold, wmk, u0, x[k], rk4_n);
            x.push(xn);
        }
    }
    let signals = Signals {
        u_d,
        u_q,
        i_d: x.iter().map(|v| v[0]).collect(),
        i_q: x.iter().map(|v| v[1]).collect(),
        w_m: wm,
        ..Signals::default()
    };
    (experiment("ipm_test", H, signals), x)
}

/// Simulates from the measured `x0`; returns states and (if `sens`) sensitivities 2 × n_θ.
fn simulate<M: GreyBoxModel>(
    m: &M,
    e: &Experiment,
    th: &[f64],
    sens: bool,
) -> (Vec<[f64; 2]>, Vec<Vec<f64>>) {
    let p = Prepared::new(m, e).unwrap();
    let c = m.coefficients(th, &p.inputs).unwrap();
    let nt = th.len();
    let mut x = vec![[p.x0[0], p.x0[1]]];
    let mut s = vec![vec![0.0; 2 * nt]];
    for k in 0..p.n - 1 {
        let mut xn = [0.0; 2];
        if sens {
            let mut sn = vec![0.0; 2 * nt];
            let analytic = m.sensitivities().expect("analytic sensitivities");
            analytic.step_sensitivity(&c, &p.inputs, k, &x[k], &s[k], &mut xn, &mut sn);
            s.push(sn);
        } else {
            m.step(&c, &p.inputs, k, &x[k], &mut xn);
        }
        x.push(xn);
    }
    (x, s)
}

fn norm(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

/// Largest `‖a_k − b_k‖ / ‖b_k‖` over the trajectory.
fn max_rel(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    a.iter().zip(b).map(|(a, b)| norm([a[0] - b[0], a[1] - b[1]]) / norm(*b)).fold(0.0, f64::max)
}

/// Largest deviation of sensitivity entries, each (state, parameter) entry relative to
/// that entry's largest magnitude over the trajectory.
fn max_rel_sens(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..a[0].len() {
        let scale = b.iter().map(|s| s[i].abs()).fold(0.0, f64::max);
        assert!(scale > 0.0, "sensitivity entry {i} is identically zero");
        for (a, b) in a.iter().zip(b) {
            worst = worst.max((a[i] - b[i]).abs() / scale);
        }
    }
    worst
}

fn varying_speed(k: usize) -> f64 {
    150.0 + 100.0 * (2.0 * std::f64::consts::PI * 12.0 * k as f64 * H).sin()
}

#[test]
fn one_step_matches_rk4() {
    for hold in HOLDS {
        for w_m in [0.0, 37.0, -250.0, 250.0] {
            let (e, x) = trajectory(hold, 16, |_| w_m, 4000);
            let (xs, _) = simulate(&PmsmIpm::new(N_P, hold), &e, &THETA, false);
            let err = max_rel(&xs[..2], &x[..2]);
            println!("one step {hold} w_m = {w_m}: max rel err vs RK4 {err:.2e}");
            assert!(err <= 1e-9, "{hold} w_m = {w_m}: {err:e}");
        }
    }
}

#[test]
fn trajectory_matches_rk4() {
    for hold in HOLDS {
        let (e, x) = trajectory(hold, 201, varying_speed, 2000);
        let (xs, _) = simulate(&PmsmIpm::new(N_P, hold), &e, &THETA, false);
        let (xs_s, _) = simulate(&PmsmIpm::new(N_P, hold), &e, &THETA, true);
        let err = max_rel(&xs, &x);
        println!("200 steps {hold}: max rel err vs RK4 {err:.2e}");
        assert!(err <= 1e-9, "{hold}: {err:e}");
        // step and step_sensitivity give the same state
        assert!(max_rel(&xs_s, &xs) <= 1e-14);
    }
}

#[test]
fn wrong_hold_is_detectably_wrong() {
    // guards the tests above against a hold that is silently ignored
    let (e, x) = trajectory(VoltageHold::Stator, 201, varying_speed, 200);
    let (xs, _) = simulate(&PmsmIpm::new(N_P, VoltageHold::Dq), &e, &THETA, false);
    assert!(max_rel(&xs, &x) > 1e-4);
}

#[test]
fn high_speed_matches_rk4() {
    // φ = ω_e h up to 1 rad (substeps), and up to 40 rad (scaling and squaring)
    for hold in HOLDS {
        for (phi, rk4_n) in
            [(0.25, 2000), (0.5, 2000), (0.51, 2000), (1.0, 4000), (-1.0, 4000), (40.0, 40000)]
        {
            let w_m = phi / (f64::from(N_P) * H);
            let (e, x) = trajectory(hold, 40, |k| w_m * (1.0 - 0.002 * k as f64), rk4_n);
            let (xs, s) = simulate(&PmsmIpm::new(N_P, hold), &e, &THETA, true);
            let err = max_rel(&xs, &x);
            println!("{hold} φ = {phi}: max rel err vs RK4 {err:.2e}");
            assert!(err <= 1e-9, "{hold} φ = {phi}: {err:e}");
            assert!(s.iter().flatten().all(|v| v.is_finite()));
        }
    }
}

#[test]
fn stiff_parameters_match_rk4() {
    // R_s h/L_d = 50: the scaling-and-squaring path at low speed
    let th = [0.35, 1.4e-6, 7.5e-3, 0.4164];
    for hold in HOLDS {
        let e = trajectory(hold, 16, |_| 100.0, 10).0;
        let p = Prepared::new(&PmsmIpm::new(N_P, hold), &e).unwrap();
        let w = DqView::try_new(&e).unwrap().w_m();
        let mut x = [p.x0[0], p.x0[1]];
        let (xs, _) = simulate(&PmsmIpm::new(N_P, hold), &e, &th, false);
        let mut worst: f64 = 0.0;
        for k in 0..10 {
            let w_m = 0.5 * (w[k] + w[k + 1]);
            let u0 = [p.inputs.u0(k).re, p.inputs.u0(k).im];
            x = rk4_period(th, hold, w_m, u0, x, 50_000);
            let err = norm([xs[k + 1][0] - x[0], xs[k + 1][1] - x[1]]) / norm(x);
            assert!(err <= 1e-9, "{hold} k = {k}: {err:e}");
            worst = worst.max(err);
        }
        println!("stiff (R_s h/L_d = 50) {hold}: max rel err vs RK4 {worst:.2e}");
    }
}

#[test]
fn equals_spm_when_not_salient() {
    let l = 5e-3;
    let th_ipm = [THETA[0], l, l, THETA[3]];
    let th_spm = [THETA[0], l, THETA[3]];
    for hold in HOLDS {
        for (n, label) in [(2, "one step"), (201, "200 steps")] {
            let e = trajectory(hold, n.max(16), varying_speed, 10).0;
            let (xi, si) = simulate(&PmsmIpm::new(N_P, hold), &e, &th_ipm, true);
            let (xs, ss) = simulate(&PmsmSpm::new(N_P, hold), &e, &th_spm, true);
            let n_cmp = n.min(xi.len());
            let err = max_rel(&xi[..n_cmp], &xs[..n_cmp]);
            // SPM's ∂/∂l_s is ∂/∂l_d + ∂/∂l_q of the IPM
            let mapped: Vec<Vec<f64>> =
                si[1..n_cmp].iter().map(|s| vec![s[0], s[1] + s[2], s[3], s[4], s[5] + s[6], s[7]]).collect();
            let err_s = max_rel_sens(&mapped, &ss[1..n_cmp]);
            println!("{label} {hold}: vs SPM state {err:.2e}, sensitivity {err_s:.2e}");
            assert!(err <= 1e-12, "{hold} {label}: state {err:e}");
            assert!(err_s <= 1e-12, "{hold} {label}: sensitivity {err_s:e}");
        }
    }
}

#[test]
fn sensitivities_match_finite_differences() {
    for hold in HOLDS {
        let e = trajectory(hold, 501, varying_speed, 10).0;
        let m = PmsmIpm::new(N_P, hold);
        // away from the data-generating θ so that the currents are not at a special point
        let th = [0.41, 2.9e-3, 8.1e-3, 0.40];
        let (_, s) = simulate(&m, &e, &th, true);
        let mut fd = vec![vec![0.0; 8]; s.len()];
        for j in 0..4 {
            let d = 1e-6 * th[j];
            let (mut tp, mut tm) = (th, th);
            tp[j] += d;
            tm[j] -= d;
            let (xp, _) = simulate(&m, &e, &tp, false);
            let (xm, _) = simulate(&m, &e, &tm, false);
            for k in 0..s.len() {
                for i in 0..2 {
                    fd[k][4 * i + j] = (xp[k][i] - xm[k][i]) / (2.0 * d);
                }
            }
        }
        let err = max_rel_sens(&s[1..], &fd[1..]);
        println!("500 steps {hold}: sensitivities vs central FD {err:.2e}");
        assert!(err <= 1e-6, "{hold}: {err:e}");
    }
}

#[test]
fn invalid_parameters_are_named() {
    let e = trajectory(VoltageHold::Stator, 16, |_| 100.0, 10).0;
    let m = PmsmIpm::new(N_P, VoltageHold::Stator);
    let p = Prepared::new(&m, &e).unwrap();
    let cases = [
        ([0.0, 3e-3, 7e-3, 0.4], "r_s"),
        ([-0.3, 3e-3, 7e-3, 0.4], "r_s"),
        ([f64::NAN, 3e-3, 7e-3, 0.4], "r_s"),
        ([0.3, 0.0, 7e-3, 0.4], "l_d"),
        ([0.3, f64::INFINITY, 7e-3, 0.4], "l_d"),
        ([0.3, 3e-3, -7e-3, 0.4], "l_q"),
        ([0.3, 3e-3, f64::NAN, 0.4], "l_q"),
        ([0.3, 3e-3, 7e-3, f64::NAN], "k_e"),
        ([0.3, 3e-3, 7e-3, f64::NEG_INFINITY], "k_e"),
        ([1e300, 1e-12, 7e-3, 0.4], "l_d"),
    ];
    for (th, name) in cases {
        match m.coefficients(&th, &p.inputs) {
            Err(Error::InvalidParameter { name: got, .. }) => assert_eq!(got, name, "{th:?}"),
            other => panic!("{th:?}: expected InvalidParameter({name}), got {other:?}"),
        }
    }
    assert!(matches!(m.coefficients(&[0.3, 3e-3, 7e-3], &p.inputs), Err(Error::InvalidOption { .. })));
}

#[test]
fn extreme_parameters_within_bounds_do_not_panic() {
    let e = trajectory(VoltageHold::Stator, 16, |_| 250.0, 10).0;
    for hold in HOLDS {
        let m = PmsmIpm::new(N_P, hold);
        for lower in m.parameters().iter().map(|p| p.lower) {
            assert!(lower > 0.0 || lower == f64::NEG_INFINITY);
        }
        for th in [
            [1e-12, 1e-12, 1e-12, 0.0],
            [1e3, 1e-12, 10.0, -5.0],
            [1e-12, 10.0, 1e-12, 1e3],
            [1e6, 1e-9, 1e-9, 0.4],
        ] {
            let (x, s) = simulate(&m, &e, &th, true);
            assert_eq!(x.len(), 16);
            assert_eq!(s.len(), 16);
        }
    }
}

#[test]
fn metadata() {
    let m = PmsmIpm::new(N_P, VoltageHold::Stator);
    assert_eq!(m.hold(), VoltageHold::Stator);
    assert_eq!(m.n_p(), N_P);
    assert_eq!(m.name(), "pmsm_ipm");
    let outputs: Vec<String> = m.outputs().into_iter().map(|o| o.name).collect();
    assert_eq!(outputs, ["id", "iq"]);
    let names: Vec<&str> = m.parameters().iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["r_s", "l_d", "l_q", "k_e"]);
    assert!(m.sensitivities().is_some());
    assert_eq!((m.n_states(), m.n_outputs()), (2, 2));
    let mut m = PmsmIpm::new(N_P, VoltageHold::Dq);
    m.parameters_mut()[3].fixed = true;
    assert!(m.parameters()[3].fixed);
    assert_eq!(m.hold(), VoltageHold::Dq);
}
