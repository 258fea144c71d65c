//! What a motor setup adds to a fit (MODEL.md §3, §4): a known cable resistance taken out
//! of `r_s`, and winding and magnet temperatures derived from `r_s` and `psi_f`.

use crate::common::{Rng, exciting_signals, pmsm_options, simulate_into};
use approx::{assert_abs_diff_eq, assert_relative_eq, relative_eq};
use greybox::pmsm::{
    ALPHA_COPPER, BETA_NDFEB, HoldChoice, PmsmFitOptions, PmsmSpm, ThermalReference, VoltageHold, fit_pmsm,
};

const N_P: u32 = 4;
const H: f64 = 1e-4;
/// Reference point: 20 °C, R_s0 = 0.9 Ω, ψ_f0 = 0.11 V s.
const T0: f64 = 20.0;
const R_S0: f64 = 0.9;
const PSI_F0: f64 = 0.11;
/// `K_e = √(3/2) n_p ψ_f` [V s/rad] (MODEL.md §2).
fn k_e(psi_f: f64) -> f64 {
    1.5f64.sqrt() * f64::from(N_P) * psi_f
}

fn record(r_total: f64, psi_f: f64, noise: f64, seed: u64) -> greybox::Experiment {
    let mut rng = Rng(seed);
    let theta = [r_total, 4.5e-3, k_e(psi_f)];
    let s = exciting_signals(8000, H, 250.0, 60.0, theta[2], &mut rng);
    let clean = simulate_into(&PmsmSpm::new(N_P, VoltageHold::Stator), &theta, H, s);
    let mut s = greybox::pmsm::DqView::try_new(&clean).unwrap().to_signals();
    for v in s.i_d.iter_mut().chain(s.i_q.iter_mut()) {
        *v += noise * rng.normal();
    }
    s.into_experiment("warm", H).unwrap()
}

fn options() -> PmsmFitOptions {
    PmsmFitOptions {
        hold: HoldChoice::Stator,
        thermal: Some(ThermalReference::try_new(T0, Some(R_S0), Some(PSI_F0)).unwrap()),
        ..pmsm_options(N_P)
    }
}

/// A warm motor (winding 75 °C, magnets 60 °C) gives its temperatures back within 1 K,
/// noise-free and with current noise, each within 3 standard errors.
#[test]
fn temperatures_come_back_from_a_warm_motor() {
    let (t_w, t_m) = (75.0, 60.0);
    let r_s = R_S0 * (1.0 + ALPHA_COPPER * (t_w - T0));
    let psi_f = PSI_F0 * (1.0 + BETA_NDFEB * (t_m - T0));
    for (noise, seed) in [(0.0, 1), (0.02, 2), (0.02, 3)] {
        let fit = fit_pmsm(&[record(r_s, psi_f, noise, seed)], &options()).unwrap();
        for (name, truth) in [("t_winding", t_w), ("t_magnet", t_m)] {
            let d = fit.derived(name).unwrap_or_else(|| panic!("{name} derived"));
            assert_eq!(d.unit, "degC");
            let z = (d.value - truth) / d.std_error;
            eprintln!(
                "noise {noise}: {name} {:.4} ± {:.4} °C (truth {truth}), z {z:+.2}",
                d.value, d.std_error
            );
            assert!((d.value - truth).abs() < 1.0, "{name}: {} °C", d.value);
            assert!(noise == 0.0 || z.abs() < 3.0, "{name}: z = {z}");
        }
    }
}

/// A known cable resistance is taken out of `r_s`: the fit sees R_s + R_cable and reports
/// the motor's R_s, with the cable apart.
#[test]
fn cable_resistance_is_reported_apart() {
    let cable = 0.35;
    let e = record(R_S0 + cable, PSI_F0, 0.0, 4);
    let fit =
        fit_pmsm(std::slice::from_ref(&e), &PmsmFitOptions { cable_resistance: cable, ..options() }).unwrap();
    assert_eq!(fit.cable_resistance, cable);
    let r_s = fit.parameter("r_s").unwrap().value;
    assert!(relative_eq!(r_s, R_S0, max_relative = 1e-7), "r_s {r_s}");
    // Without the cable the fit sees the sum, and the winding looks hot.
    let naive = fit_pmsm(&[e], &options()).unwrap();
    assert_relative_eq!(naive.parameter("r_s").unwrap().value, R_S0 + cable, max_relative = 1e-7);
    assert!(naive.derived("t_winding").unwrap().value > 100.0);
    // A negative cable is an error naming it.
    let err =
        fit_pmsm(&[record(R_S0, PSI_F0, 0.0, 5)], &PmsmFitOptions { cable_resistance: -0.1, ..options() })
            .unwrap_err();
    assert!(err.to_string().contains("cable"), "{err}");
}

#[test]
fn thermal_reference_refuses_bad_values() {
    assert!(ThermalReference::try_new(f64::NAN, Some(1.0), None).is_err());
    let err = ThermalReference::try_new(20.0, Some(-1.0), None).unwrap_err();
    assert!(err.to_string().contains("r_s0"), "{err}");
    assert!(ThermalReference::try_new(20.0, None, Some(0.0)).unwrap_err().to_string().contains("psi_f0"));
    // Only what is known is derived.
    let t = ThermalReference::try_new(20.0, Some(1.0), None).unwrap();
    let d = t.temperatures(1.0 + ALPHA_COPPER * 10.0, 0.0, 0.1, 0.0, None);
    assert_eq!(d.len(), 1);
    assert!((d[0].value - 30.0).abs() < 1e-9);
}

/// The temperatures take the intervals of `r_s` and `psi_f` through their linear
/// functions: the winding's ends in order (α > 0), the magnet's swapped (β < 0: more flux
/// is a colder magnet); without intervals the fit sets `± t·se`.
#[test]
fn temperatures_carry_the_parameters_intervals() {
    let t = ThermalReference::try_new(20.0, Some(1.0), Some(0.1)).unwrap();
    let f_w = |r: f64| 20.0 + (r - 1.0) / ALPHA_COPPER;
    let f_m = |p: f64| 20.0 + (p / 0.1 - 1.0) / greybox::pmsm::BETA_NDFEB;
    let d = t.temperatures(1.04, 0.01, 0.099, 0.0002, Some([[1.02, 1.07], [0.0986, 0.0995]]));
    let (w, m) = (&d[0], &d[1]);
    assert_eq!((w.name.as_str(), m.name.as_str()), ("t_winding", "t_magnet"));
    let close = |a: [f64; 2], b: [f64; 2]| {
        assert_abs_diff_eq!(a[0], b[0], epsilon = 1e-9);
        assert_abs_diff_eq!(a[1], b[1], epsilon = 1e-9);
    };
    close(w.ci95.unwrap(), [f_w(1.02), f_w(1.07)]);
    close(m.ci95.unwrap(), [f_m(0.0995), f_m(0.0986)]);
    assert!(w.ci95.unwrap()[0] < w.value && w.value < w.ci95.unwrap()[1]);
    assert!(m.ci95.unwrap()[0] < m.value && m.value < m.ci95.unwrap()[1]);
    assert!(t.temperatures(1.04, 0.01, 0.099, 0.0002, None).iter().all(|q| q.ci95.is_none()));
    // A NaN end stays NaN (not collapsed to the other end).
    let d = t.temperatures(1.04, 0.01, 0.099, 0.0002, Some([[f64::NAN, 1.07], [0.0986, 0.0995]]));
    assert!(d[0].ci95.unwrap().iter().any(|e| e.is_nan()), "{:?}", d[0].ci95);
}
