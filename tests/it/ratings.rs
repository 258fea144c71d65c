//! The ratings in the derived quantities (issue 33, deliverable 5), checked by hand on the
//! bundled sample (a verbatim cut of a shared log): `k_t_rms`, `k_v` and `k_m` from the
//! fitted `k_e`, `r_s` with the conventions the report states, and `k_t · k_v` = 8.27 (the
//! ODrive/VESC relation between the torque constant per peak ampere and K_v).

use greybox::pmsm::{PmsmFitOptions, fit_pmsm, read_log};

#[test]
fn ratings_match_the_hand_calculation() {
    let log =
        read_log(concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"), &Default::default()).unwrap();
    let fit = fit_pmsm(&[log], &PmsmFitOptions::new(4)).unwrap();
    let p = |n: &str| fit.parameter(n).unwrap().value;
    let d = |n: &str| fit.derived(n).unwrap().clone();
    let (k_e, r_s) = (p("k_e"), p("r_s"));
    // By hand: peak line-to-line back-EMF per rpm is √2 k_e (2π/60); K_v is its inverse.
    let k_v = 1.0 / (2f64.sqrt() * k_e * 2.0 * std::f64::consts::PI / 60.0);
    assert!((d("k_v").value / k_v - 1.0).abs() < 1e-12);
    // Torque per RMS ampere: k_t = 1.5 n_p ψ_f per peak ampere, × √2.
    let k_t = 1.5 * 4.0 * p_psi(&fit);
    assert!((d("k_t_rms").value / (2f64.sqrt() * k_t) - 1.0).abs() < 1e-12);
    // Motor constant: torque per √W of copper loss 3 r_s I_rms², at I_rms = 1 A.
    let k_m = (2f64.sqrt() * k_t) / (3.0 * r_s).sqrt();
    assert!((d("k_m").value / k_m - 1.0).abs() < 1e-12);
    assert!((d("k_t").value * d("k_v").value - 8.2699).abs() < 1e-4);
    // Standard errors: relative as k_e's for k_v; k_m's from both, with their correlation.
    let rel = |q: &greybox::model::DerivedEstimate| q.std_error / q.value;
    let se = |n: &str| fit.parameter(n).unwrap().std_error;
    assert!((rel(&d("k_v")) / (se("k_e") / k_e) - 1.0).abs() < 1e-9);
    let bound = se("k_e") / k_e + 0.5 * se("r_s") / r_s;
    assert!(rel(&d("k_m")) <= bound * (1.0 + 1e-9) && rel(&d("k_m")) > 0.0);
}

/// ψ_f of the fit \[V s\].
fn p_psi(fit: &greybox::pmsm::PmsmFit) -> f64 {
    fit.derived("psi_f").unwrap().value
}
