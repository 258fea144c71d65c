//! The firmware core's salient step (`Ipm`, the augmented exponential): at equal
//! inductances it is the surface-magnet closed form; both observers follow a salient
//! machine simulated by it from wrong starts, in `f64` and `f32`; a bad `L_q` and a
//! negative running `R_s` are named.

mod common;

use greybox_observer::{
    Adaptation, Aug, Coefficients, Complex, Field, Hold, Ipm, Kalman, Machine, Mras, Noise, Plant, Real,
    SENS_ALL, SENS_NONE, SENS_R_K, Sample, Settings, Spm, StepError, advance_substeps,
    advance_substeps_transition,
};

const N_P: u32 = 3;
const L_D: f64 = 3e-3;
const L_Q: f64 = 7e-3;
const R_S: f64 = 0.4;
const K_E: f64 = 0.55;
const H: f64 = 1.25e-4;

#[test]
fn at_equal_inductances_the_salient_step_is_the_surface_step() {
    for hold in [Hold::Stator, Hold::Dq] {
        let mut s = Settings::<f64>::new(4, 4.5e-3, 1e-4);
        s.hold = hold;
        let (spm, ipm) = (Spm::<f64>::new(&s), Ipm::new(&s, 4.5e-3).unwrap());
        for (x, u, w_m) in [
            (Complex::new(1.0, 5.0), (-3.0, 40.0), 100.0),
            (Complex::new(-4.0, -2.0), (10.0, -80.0), -250.0),
            (Complex::new(0.0, 0.0), (2.0, 1.0), 0.0),
            (Complex::new(3.0, -7.0), (-20.0, 150.0), 900.0),
        ] {
            let sample = Sample { i_d: x.re, i_q: x.im, u_d: u.0, u_q: u.1, w_m };
            let a = spm.step(x, 0.54, 0.9, &sample, false).unwrap_or_else(|e| match e {});
            let b = ipm.step(x, 0.54, 0.9, &sample, false).unwrap();
            for (name, p, q) in
                [("next", a.next, b.next), ("phi_k", a.phi_k, b.phi_k), ("phi_r", a.phi_r, b.phi_r)]
            {
                assert!(
                    (p - q).norm() <= 1e-12 * p.norm().max(1e-3),
                    "{hold:?} w_m {w_m}: {name} {p} vs {q}"
                );
            }
        }
    }
}

/// `n` samples of a salient machine driven open loop (`common::open_loop`, as
/// `observers.rs` drives its surface machine; stator hold).
fn simulate(n: usize) -> Vec<Sample<f64>> {
    common::open_loop(&Ipm::new(&Settings::new(N_P, L_D, H), L_Q).unwrap(), n, H, K_E, R_S, -6.0)
}

/// The MRAS and the filter of the salient machine over `samples` in precision `T`, started
/// 20 % low in `K_e` and 50 % high in `R_s`: their last `(k_e, r_s)` as f64.
fn run<T: Real>(samples: &[Sample<f64>]) -> [(f64, f64); 2] {
    let mut s = Settings::new(N_P, T::c(L_D), T::c(H));
    s.adaptation = Adaptation::Normalised;
    (s.k_e0, s.r_s0) = (T::c(0.8 * K_E), T::c(1.5 * R_S));
    let machine = Machine::of(&s, Some(T::c(L_Q))).unwrap();
    assert!(matches!(machine, Machine::Ipm(_)));
    let mut mras = Mras::new(s, machine).unwrap();
    let mut ekf = Kalman::new(s, machine, Noise::for_machine(T::c(1e-3), s.r_s0, s.k_e0)).unwrap();
    let (mut m, mut e) = (mras.output(), mras.output());
    for x in samples {
        let x = Sample {
            i_d: T::c(x.i_d),
            i_q: T::c(x.i_q),
            u_d: T::c(x.u_d),
            u_q: T::c(x.u_q),
            w_m: T::c(x.w_m),
        };
        m = mras.update(&x).unwrap();
        e = ekf.update(&x).unwrap();
    }
    let f = |v: T| v.to_f64().unwrap();
    [(f(m.k_e), f(m.r_s)), (f(e.k_e), f(e.r_s))]
}

#[test]
fn both_observers_reach_a_salient_truth_in_f64_and_f32() {
    let samples = simulate(48_000);
    assert!(samples.iter().filter(|s| s.i_d.abs() > 0.5).count() > 10_000, "the R_s law must be active");
    for (precision, ends, tol) in [("f64", run::<f64>(&samples), 1e-9), ("f32", run::<f32>(&samples), 1e-4)] {
        for (name, (k_e, r_s)) in ["MRAS", "EKF"].iter().zip(ends) {
            assert!((k_e / K_E - 1.0).abs() < tol, "{precision} {name} K_e {k_e}");
            assert!((r_s / R_S - 1.0).abs() < 10.0 * tol, "{precision} {name} R_s {r_s}");
        }
    }
}

#[test]
fn a_bad_l_q_and_a_negative_resistance_are_named() {
    let s = Settings::new(N_P, L_D, H);
    for l_q in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        assert_eq!(Machine::of(&s, Some(l_q)).err(), Some(Field::LQ), "{l_q}");
    }
    assert_eq!(Field::LQ.name(), "l_q");
    assert!(matches!(Machine::of(&s, Some(L_D)), Ok(Machine::Spm(_))));
    assert!(matches!(Machine::of(&s, None), Ok(Machine::Spm(_))));
    let ipm = Ipm::new(&s, L_Q).unwrap();
    let x = Sample { i_d: 0.0, i_q: 1.0, u_d: 0.0, u_q: 10.0, w_m: 50.0 };
    assert_eq!(ipm.step(Complex::new(0.0, 1.0), K_E, -0.1, &x, false).err(), Some(StepError::Resistance));
    assert_eq!(ipm.step(Complex::new(0.0, 1.0), f64::NAN, R_S, &x, false).err(), Some(StepError::BackEmf));
    // A period too long for 64 substeps of the series.
    let fast = Sample { w_m: 1e7, ..x };
    assert_eq!(ipm.step(Complex::new(0.0, 1.0), K_E, R_S, &fast, false).err(), Some(StepError::TooLong));
}

/// The salient transition `Φ = ∂i[k+1]/∂i[k]` (the series' homogeneous part) is the step's
/// linearity in the current, and at equal inductances the closed form's rotation and decay.
#[test]
fn the_salient_transition_is_the_steps_linearity() {
    for hold in [Hold::Stator, Hold::Dq] {
        let mut s = Settings::<f64>::new(N_P, L_D, H);
        s.hold = hold;
        let ipm = Ipm::new(&s, L_Q).unwrap();
        for (x, w_m) in [
            (Complex::new(2.0, -3.0), 150.0),
            (Complex::new(-1.0, 8.0), -900.0),
            (Complex::new(0.0, 0.0), 0.0),
            // ρ ≈ 1.9: four substeps, the transition their product.
            (Complex::new(1.0, -2.0), 5000.0),
        ] {
            let sample = Sample { i_d: x.re, i_q: x.im, u_d: -5.0, u_q: 60.0, w_m };
            let (st, phi) = ipm.step_transition(x, K_E, R_S, &sample).unwrap();
            assert_eq!(st, ipm.step(x, K_E, R_S, &sample, false).unwrap());
            for (col, dx) in [(0, Complex::new(1.0, 0.0)), (1, Complex::new(0.0, 1.0))] {
                let d = ipm.step(x + dx, K_E, R_S, &sample, false).unwrap().next - st.next;
                assert!(
                    (d.re - phi[0][col]).abs() < 1e-12 && (d.im - phi[1][col]).abs() < 1e-12,
                    "{hold:?} {w_m}"
                );
            }
        }
        let (spm, ipm) = (Spm::new(&s), Ipm::new(&s, L_D).unwrap());
        let sample = Sample { i_d: 1.0, i_q: 2.0, u_d: 3.0, u_q: 50.0, w_m: 300.0 };
        let a =
            spm.step_transition(Complex::new(1.0, 2.0), K_E, R_S, &sample).unwrap_or_else(|e| match e {}).1;
        let b = ipm.step_transition(Complex::new(1.0, 2.0), K_E, R_S, &sample).unwrap().1;
        for r in 0..2 {
            for c in 0..2 {
                assert!(
                    (a[r][c] - b[r][c]).abs() < 1e-13,
                    "{hold:?} Φ[{r}][{c}]: {} vs {}",
                    a[r][c],
                    b[r][c]
                );
            }
        }
    }
}

/// The transition summed in the step's loop leaves the step's numbers as they are alone, to
/// the bit, whichever sensitivities it carries; within one substep `Φ` is, to the bit, the
/// homogeneous propagation of each unit current; over several, their product.
#[test]
fn the_transition_in_the_steps_loop_changes_no_bit() {
    fn both<const S: u8>(c: &Coefficients<f64>, hold: Hold, w_e: f64, emf: f64, z0: Aug<f64>) -> [f64; 4] {
        let (mut a, mut b) = (z0, z0);
        assert!(advance_substeps::<f64, S>(c, hold, w_e, emf, &mut a, 1.0));
        let phi = advance_substeps_transition::<f64, S>(c, hold, w_e, emf, &mut b, 1.0).unwrap();
        assert_eq!(format!("{a:?}"), format!("{b:?}"), "{hold:?} w_e {w_e}");
        phi
    }
    let c = Coefficients::at(H, R_S, L_D, L_Q, K_E);
    for hold in [Hold::Stator, Hold::Dq] {
        for w_m in [0.0, 37.0, -420.0, 900.0, -5000.0] {
            let (w_e, emf) = (f64::from(N_P) * w_m, 0.816_496_580_927_726 * w_m);
            let z0 = Aug { x: [1.5, -4.0], v: [-12.0, 55.0], ..Aug::default() };
            let phi = both::<SENS_R_K>(&c, hold, w_e, emf, z0);
            assert_eq!(both::<SENS_ALL>(&c, hold, w_e, emf, z0), phi);
            assert_eq!(both::<SENS_NONE>(&c, hold, w_e, emf, z0), phi);
            let one_substep = c.rho(w_e) <= greybox_observer::RHO_MAX;
            for (col, x) in [(0, [1.0, 0.0]), (1, [0.0, 1.0])] {
                let mut u = Aug { x, ..Aug::default() };
                assert!(advance_substeps::<f64, SENS_NONE>(&c, hold, w_e, emf, &mut u, 0.0));
                let (d, q) = (phi[col], phi[2 + col]);
                if one_substep {
                    assert_eq!((u.x[0].to_bits(), u.x[1].to_bits()), (d.to_bits(), q.to_bits()), "w_m {w_m}");
                } else {
                    assert!((u.x[0] - d).abs() < 1e-13 && (u.x[1] - q).abs() < 1e-13, "w_m {w_m}");
                }
            }
        }
    }
}
