//! What a motor setup adds to a fit (MODEL.md §3, §4): a known cable resistance taken out
//! of `r_s`, and winding and magnet temperatures derived from `r_s` and `psi_f`.

use crate::common::{Rng, exciting_signals, pmsm_options, simulate_into};
use approx::{assert_relative_eq, relative_eq};
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
    let d = t.temperatures(1.0 + ALPHA_COPPER * 10.0, 0.0, 0.1, 0.0);
    assert_eq!(d.len(), 1);
    assert!((d[0].value - 30.0).abs() < 1e-9);
}
