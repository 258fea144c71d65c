//! The ratings in the derived quantities (issue 33, deliverable 5), checked by hand on the
//! bundled sample (a verbatim cut of a shared log): `k_t_rms`, `k_v` and `k_m` from the
//! fitted `k_e`, `r_s` with the conventions the report states, and `k_t · k_v` = 8.27 (the
//! ODrive/VESC relation between the torque constant per peak ampere and K_v).

use approx::assert_relative_eq;
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

/// The derived quantities' intervals are the fit's statements about `k_e` carried through
/// their functions: with instrumental variables the sample's `k_e` interval is the
/// restricted (asymmetric) one, and `k_t = √1.5 k_e`, `psi_f = √(2/3) k_e/n_p`, `k_t_rms =
/// √3 k_e` keep its ends times their factors, `k_v = c/k_e` its ends swapped; `k_m`, of
/// `r_s` and `k_e`, is `± q·se` at the heavier of their quantiles (longer side over
/// standard error). The prediction-error fit's are `± t·se` throughout, the quantile of its
/// parameters' intervals.
#[test]
fn derived_intervals_carry_the_parameters_intervals() {
    use greybox::pmsm::{Estimator, fit_pmsm_by};
    let log =
        read_log(concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"), &Default::default()).unwrap();
    let options = PmsmFitOptions::new(4);
    let iv = fit_pmsm_by(std::slice::from_ref(&log), &options, Estimator::InstrumentalVariables).unwrap();
    assert!(iv.uncertainty.restricted, "the sample's IV fit gives restricted intervals");
    let k_e = iv.parameter("k_e").unwrap();
    let [lo, hi] = k_e.ci95;
    // Asymmetric: otherwise the mapping could not be told from ± t·se.
    assert!(((hi - k_e.value) / (k_e.value - lo) - 1.0).abs() > 1e-3, "k_e interval {lo} {hi}");
    let ci = |n: &str| iv.derived(n).unwrap().ci95.unwrap();
    let same = |a: [f64; 2], b: [f64; 2]| {
        assert_relative_eq!(a[0], b[0], max_relative = 1e-12);
        assert_relative_eq!(a[1], b[1], max_relative = 1e-12);
    };
    same(ci("k_t"), [1.5f64.sqrt() * lo, 1.5f64.sqrt() * hi]);
    let psi = (2.0f64 / 3.0).sqrt() / 4.0;
    same(ci("psi_f"), [psi * lo, psi * hi]);
    same(ci("k_t_rms"), [3f64.sqrt() * lo, 3f64.sqrt() * hi]);
    let per_volt = 60.0 / (2.0 * std::f64::consts::PI * 2f64.sqrt());
    same(ci("k_v"), [per_volt / hi, per_volt / lo]);
    let quantile = |n: &str| {
        let p = iv.parameter(n).unwrap();
        (p.ci95[1] - p.value).max(p.value - p.ci95[0]) / p.std_error
    };
    let (q, t) =
        (quantile("r_s").max(quantile("k_e")), greybox::estimate::t_quantile_975(iv.uncertainty.dof));
    assert!(q > 1.001 * t, "the restricted intervals' heavier quantile {q} against t {t}");
    let k_m = iv.derived("k_m").unwrap();
    same(ci("k_m"), [k_m.value - q * k_m.std_error, k_m.value + q * k_m.std_error]);

    let pem = fit_pmsm(&[log], &options).unwrap();
    let t = greybox::estimate::t_quantile_975(pem.uncertainty.dof);
    let k_e = pem.parameter("k_e").unwrap();
    // The half width is 3e-7 of the value: the difference keeps some 1e-10 of it.
    assert_relative_eq!((k_e.ci95[1] - k_e.value) / k_e.std_error, t, max_relative = 1e-8);
    for q in &pem.derived {
        same(q.ci95.unwrap(), [q.value - t * q.std_error, q.value + t * q.std_error]);
    }
}

/// The mapping keeps every interval ordered and around its value for a back-EMF constant of
/// either sign (a speed column of the other sign gives a negative `k_e`), and gives `k_v` no
/// mapped interval where `k_e`'s holds 0 (`1/k_e` is unbounded there): the fit's `± t·se`.
#[test]
fn derived_intervals_hold_their_values_for_either_sign() {
    use greybox::pmsm::{MotorKind, derived};
    for (k_e, ci_k) in [(0.54, [0.53, 0.56]), (-0.54, [-0.56, -0.53])] {
        let theta = [0.9, 0.0045, k_e];
        let ci = [[0.89, 0.93], [0.0044, 0.0046], ci_k];
        for q in derived(MotorKind::Spm, 4, &theta, &[0.01, 1e-5, 0.005], 0.1, Some(&ci)) {
            let [lo, hi] = q.ci95.unwrap();
            assert!(
                lo < q.value && q.value < hi,
                "{} = {} outside [{lo}, {hi}] (k_e {k_e})",
                q.name,
                q.value
            );
        }
    }
    let around_zero = derived(
        MotorKind::Spm,
        4,
        &[0.9, 0.0045, 0.01],
        &[0.01, 1e-5, 0.02],
        0.0,
        Some(&[[0.89, 0.93], [0.0044, 0.0046], [-0.03, 0.05]]),
    );
    let k_v = around_zero.iter().find(|q| q.name == "k_v").unwrap();
    assert!(k_v.ci95.is_none(), "{:?}", k_v.ci95);
}
