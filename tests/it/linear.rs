//! Linear least squares and weighted least squares (thesis 5.2.1): recovery on the
//! noise-free logs, the errors-in-variables bias on the noisy ones against the
//! prediction-error fit, sample weighting, the zero-phase prefilter, and bad input.

use crate::common::{Signals, Truth, load, pmsm_options, rel};
use approx::{assert_relative_eq, relative_eq};
use greybox::estimate::{CustomWeighting, SpeedShape, SpeedWeighting, Uniform, Weighting};
use greybox::pmsm::PmsmError;
use greybox::pmsm::{
    LinearEstimate, LinearOptions, MotorKind, PmsmFitOptions, fit_pmsm, least_squares, weighted_least_squares,
};
use greybox::{Error, Experiment, Result};

fn kind_of(t: &Truth) -> MotorKind {
    if t.salient { MotorKind::Ipm } else { MotorKind::Spm }
}

fn truths(t: &Truth) -> Vec<(&'static str, f64)> {
    if t.salient {
        vec![("r_s", t.r_s), ("l_d", t.l_d), ("l_q", t.l_q), ("k_e", t.k_e)]
    } else {
        vec![("r_s", t.r_s), ("l_s", t.l_d), ("k_e", t.k_e)]
    }
}

// ------------------------------------------------------------- (a) noise-free recovery

/// LS on a noise-free log: every parameter within `tol` (relative) of the truth.
fn assert_ls_recovers(stem: &str, tol: f64) {
    let (e, t) = load(stem);
    let ls = least_squares(&[e], t.n_p, kind_of(&t)).expect("LS runs");
    eprintln!("{stem}:\n{ls}");
    for (name, truth) in truths(&t) {
        let est = ls.value(name).unwrap();
        let err = rel(est, truth);
        eprintln!("{stem} {name}: LS {est:.7e}, truth {truth:.7e}, relative error {err:.3e}");
        assert!(
            relative_eq!(est, truth, max_relative = tol),
            "{stem} {name}: {est:e} vs truth {truth:e}: relative error {err:e}"
        );
    }
    assert!(ls.std_error.iter().chain(&ls.error_index_percent).all(|v| v.is_finite() && *v > 0.0));
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn ls_servo_spm_moves() {
    crate::common::require_shared!();
    assert_ls_recovers("servo_spm_moves", 1e-3);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn ls_servo_spm_moves_idinj() {
    crate::common::require_shared!();
    assert_ls_recovers("servo_spm_moves_idinj", 1e-3);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn ls_ipm_moves_idinj() {
    crate::common::require_shared!();
    assert_ls_recovers("ipm_moves_idinj", 1e-3);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn ls_gem_spm_moves_idinj() {
    crate::common::require_shared!();
    assert_ls_recovers("gem_spm_moves_idinj", 1e-3);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn ls_gem_ipm_moves_idinj() {
    crate::common::require_shared!();
    assert_ls_recovers("gem_ipm_moves_idinj", 1e-3);
}

// -------------------------------------------------------- (b) noisy logs: LS vs PEM

/// On a noisy log LS is biased (errors in variables, MODEL.md §5) and PEM is not: PEM
/// within 0.2 % everywhere, LS's inductance error `factor` times PEM's or more.
fn ls_vs_pem(stem: &str, factor: f64) {
    let (e, t) = load(stem);
    let kind = kind_of(&t);
    let ls = least_squares(std::slice::from_ref(&e), t.n_p, kind).expect("LS runs");
    let pem = fit_pmsm(&[e], &PmsmFitOptions { model: kind, ..pmsm_options(t.n_p) }).expect("PEM runs");
    assert!(pem.solver.success, "{stem}: {}", pem.solver.termination);
    eprintln!("LS vs PEM bias, {stem} ({kind:?} model)");
    eprintln!("| parameter | truth | LS | PEM | LS error % | PEM error % |");
    eprintln!("| --- | --- | --- | --- | --- | --- |");
    for (name, truth) in truths(&t) {
        let (l, p) = (ls.value(name).unwrap(), pem.parameter(name).unwrap().value);
        let (el, ep) = (100.0 * (l - truth) / truth, 100.0 * (p - truth) / truth);
        eprintln!("| {name} | {truth:.6e} | {l:.6e} | {p:.6e} | {el:+.3} | {ep:+.4} |");
        assert!(relative_eq!(p, truth, max_relative = 2e-3), "{stem} {name}: PEM {p} vs {truth}");
        if name.starts_with("l_") {
            assert!(
                rel(l, truth) > factor * rel(p, truth),
                "{stem} {name}: LS error {el:.3} % is not {factor}× PEM's {ep:.4} %"
            );
            assert!(l < truth, "{stem} {name}: errors in variables bias L low, LS gave {l} vs {truth}");
        }
    }
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn ls_vs_pem_servo_noisy() {
    crate::common::require_shared!();
    ls_vs_pem("servo_spm_moves_idinj_noisy", 50.0);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn ls_vs_pem_gem_ipm_noisy() {
    crate::common::require_shared!();
    ls_vs_pem("gem_ipm_moves_idinj_noisy", 50.0);
}

// ---------------------------------------------------------------- (c) weighting

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn speed_weighting_changes_the_error_indices() {
    crate::common::require_shared!();
    let (e, t) = load("servo_spm_moves_idinj_noisy");
    let low = SpeedWeighting::try_new("w_m", SpeedShape::LowSpeed { w0: 50.0 }).unwrap();
    let opts = LinearOptions::default();
    let uni =
        weighted_least_squares(std::slice::from_ref(&e), t.n_p, MotorKind::Spm, &Uniform, &opts).unwrap();
    let wls = weighted_least_squares(std::slice::from_ref(&e), t.n_p, MotorKind::Spm, &low, &opts).unwrap();
    eprintln!("uniform:\n{uni}\nlow-speed weighting:\n{wls}");
    assert!(wls.weighting.contains("low_speed"));
    for i in 0..3 {
        assert!(wls.theta[i].is_finite() && wls.error_index_percent[i].is_finite());
        let (p_u, p_w) = (uni.error_index_percent[i], wls.error_index_percent[i]);
        eprintln!(
            "{}: error index {p_u:.4} % → {p_w:.4} % ({:+.1} %)",
            uni.names[i],
            100.0 * (p_w / p_u - 1.0)
        );
        assert!(rel(p_w, p_u) > 1e-3, "{}: weighting left the error index unchanged", uni.names[i]);
    }
    // Low speed is where R_s shows (MODEL.md §6): relative to K_e, R_s is better determined.
    let ratio = |x: &LinearEstimate| x.error_index_percent[0] / x.error_index_percent[2];
    assert!(ratio(&wls) < ratio(&uni), "P(r_s)/P(k_e): {} vs uniform {}", ratio(&wls), ratio(&uni));
    assert_relative_eq!(wls.theta[2], t.k_e, max_relative = 1e-2);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn constant_weights_equal_uniform() {
    crate::common::require_shared!();
    // β = 3 everywhere (not flagged uniform) must give the LS estimate and error index:
    // both are invariant to a common scale of the weights.
    let (e, t) = load("servo_spm_moves_idinj");
    let three = CustomWeighting::new("three", |_, _| 3.0);
    let opts = LinearOptions::default();
    let a = weighted_least_squares(std::slice::from_ref(&e), t.n_p, MotorKind::Spm, &Uniform, &opts).unwrap();
    let b = weighted_least_squares(std::slice::from_ref(&e), t.n_p, MotorKind::Spm, &three, &opts).unwrap();
    for i in 0..3 {
        assert!(relative_eq!(b.theta[i], a.theta[i], max_relative = 1e-10), "{}", a.names[i]);
        assert_relative_eq!(b.error_index_percent[i], a.error_index_percent[i], max_relative = 1e-8);
        assert_relative_eq!(b.std_error[i], a.std_error[i], max_relative = 1e-8);
    }
    assert_relative_eq!(b.e2, 3.0 * a.e2, max_relative = 1e-8);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn weights_select_rows() {
    crate::common::require_shared!();
    // Zero weight on the second half of a log = LS on the first half (rows of intervals
    // ending in samples with β = 0 drop out).
    let (e, t) = load("servo_spm_moves_idinj");
    let cut = e.len() / 2;
    let w = CustomWeighting::new("first half", move |_, k| if k < cut { 1.0 } else { 0.0 });
    let whole = weighted_least_squares(
        std::slice::from_ref(&e),
        t.n_p,
        MotorKind::Spm,
        &w,
        &LinearOptions::default(),
    )
    .unwrap();
    let half = least_squares(&[e.slice(0..cut).unwrap()], t.n_p, MotorKind::Spm).unwrap();
    for i in 0..3 {
        assert!(
            relative_eq!(whole.theta[i], half.theta[i], max_relative = 1e-9),
            "{}: {} vs {}",
            half.names[i],
            whole.theta[i],
            half.theta[i]
        );
        assert_relative_eq!(whole.error_index_percent[i], half.error_index_percent[i], max_relative = 1e-6);
    }
    assert_relative_eq!(whole.theta[1], t.l_d, max_relative = 1e-3);
}

// ---------------------------------------------------------------- (d) prefilter

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn prefilter_changes_the_noisy_estimate() {
    crate::common::require_shared!();
    let (e, t) = load("servo_spm_moves_idinj_noisy");
    let ls = least_squares(std::slice::from_ref(&e), t.n_p, MotorKind::Spm).unwrap();
    let truth = [t.r_s, t.l_d, t.k_e];
    let pct = |x: &LinearEstimate| -> Vec<String> {
        x.theta.iter().zip(&truth).map(|(v, t)| format!("{:+.3} %", 100.0 * (v - t) / t)).collect()
    };
    eprintln!("no prefilter: {:?} errors {:?}", ls.theta, pct(&ls));
    for fc in [2000.0, 1000.0, 500.0, 200.0] {
        let opts = LinearOptions { prefilter: Some(fc), ..Default::default() };
        let f =
            weighted_least_squares(std::slice::from_ref(&e), t.n_p, MotorKind::Spm, &Uniform, &opts).unwrap();
        eprintln!("prefilter {fc} Hz: {:?} errors (r_s, l_s, k_e) {:?}", f.theta, pct(&f));
        assert!(f.theta.iter().chain(&f.std_error).chain(&f.error_index_percent).all(|v| v.is_finite()));
        assert_eq!(f.options, opts);
        assert!(rel(f.theta[1], ls.theta[1]) > 1e-3, "{fc} Hz: L_s unchanged by the filter");
        if fc == 500.0 {
            eprintln!("{f}");
        }
    }
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn prefilter_keeps_noise_free_estimates_close() {
    crate::common::require_shared!();
    // Filtering every signal alike commutes with the linear terms; only the products
    // ω·i do not commute exactly with the filter. Measure what that costs.
    let (e, t) = load("servo_spm_moves_idinj");
    for fc in [2000.0, 500.0] {
        let opts = LinearOptions { prefilter: Some(fc), ..Default::default() };
        let f =
            weighted_least_squares(std::slice::from_ref(&e), t.n_p, MotorKind::Spm, &Uniform, &opts).unwrap();
        let errs: Vec<f64> = f.theta.iter().zip([t.r_s, t.l_d, t.k_e]).map(|(v, t)| rel(*v, t)).collect();
        let shown: Vec<String> = errs.iter().map(|e| format!("{e:.3e}")).collect();
        eprintln!("noise-free, prefilter {fc} Hz: relative errors (r_s, l_s, k_e) {shown:?}");
        for (v, truth) in f.theta.iter().zip([t.r_s, t.l_d, t.k_e]) {
            assert!(relative_eq!(*v, truth, max_relative = 1e-2), "{fc} Hz: {errs:?}");
        }
    }
}

fn option_of<T: std::fmt::Debug>(r: Result<T>) -> String {
    match r {
        Err(Error::InvalidOption { option, reason }) => {
            eprintln!("option `{option}`: {reason}");
            option
        }
        other => panic!("expected InvalidOption, got {other:?}"),
    }
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn bad_prefilter_options_are_errors() {
    crate::common::require_shared!();
    let (e, t) = load("servo_spm_moves_idinj");
    let es = std::slice::from_ref(&e);
    for fc in [0.0, -10.0, 5000.0, 1e6, f64::NAN] {
        let opts = LinearOptions { prefilter: Some(fc), ..Default::default() };
        assert_eq!(
            option_of(weighted_least_squares(es, t.n_p, MotorKind::Spm, &Uniform, &opts)),
            "prefilter"
        );
    }
    for order in [0, 3, 7, 1000] {
        let opts = LinearOptions { prefilter: Some(500.0), filter_order: order };
        assert_eq!(
            option_of(weighted_least_squares(es, t.n_p, MotorKind::Spm, &Uniform, &opts)),
            "filter_order"
        );
        let opts = LinearOptions { prefilter: None, filter_order: order };
        assert_eq!(
            option_of(weighted_least_squares(es, t.n_p, MotorKind::Spm, &Uniform, &opts)),
            "filter_order"
        );
    }
    // The error names the experiment whose Nyquist frequency the cutoff exceeds.
    let opts = LinearOptions { prefilter: Some(5000.0), ..Default::default() };
    let msg = weighted_least_squares(es, t.n_p, MotorKind::Spm, &Uniform, &opts).unwrap_err().to_string();
    assert!(msg.contains("servo_spm_moves_idinj"), "{msg}");
}

// ---------------------------------------------------------------- robustness

fn synthetic(f: impl Fn(usize) -> (f64, f64, f64, f64, f64)) -> Experiment {
    let mut s = Signals::default();
    for k in 0..200 {
        let (ud, uq, id, iq, w) = f(k);
        s.u_d.push(ud);
        s.u_q.push(uq);
        s.i_d.push(id);
        s.i_q.push(iq);
        s.w_m.push(w);
    }
    s.into_experiment("synthetic", 1e-4).unwrap()
}

fn numerical_reason<T: std::fmt::Debug>(r: Result<T>) -> String {
    match r {
        Err(Error::Numerical { reason, .. }) => {
            eprintln!("{reason}");
            reason
        }
        other => panic!("expected Numerical, got {other:?}"),
    }
}

#[test]
fn bad_input_is_a_clear_error() {
    assert_eq!(option_of(least_squares(&[], 4, MotorKind::Spm)), "experiments");
    let a = synthetic(|k| ((k as f64).sin(), (k as f64).cos(), (0.3 * k as f64).sin(), 1.0, 10.0));
    // Experiments no longer carry n_p (one argument for all, so logs of motors with
    // different pole pairs cannot be mixed); n_p = 0 is the error.
    let err = least_squares(std::slice::from_ref(&a), 0, MotorKind::Spm).unwrap_err();
    assert!(matches!(err.domain(), Some(PmsmError::InvalidPolePairs { n_p: 0 })), "{err:?}");
    // No speed: K_e is not excited.
    let still = synthetic(|k| ((k as f64).sin(), (k as f64).cos(), (0.3 * k as f64).sin(), 1.0, 0.0));
    assert!(numerical_reason(least_squares(&[still], 4, MotorKind::Spm)).contains("`k_e`"));
    // Constant i_q, i_d = 0, constant speed: K_e's column is R_s's, scaled.
    let flat = synthetic(|k| ((k as f64).sin(), (k as f64).cos(), 0.0, 2.0, 30.0));
    let reason = numerical_reason(least_squares(std::slice::from_ref(&flat), 4, MotorKind::Spm));
    assert!(reason.contains("rank deficient") && reason.contains("`k_e`"), "{reason}");
    // In the IPM model L_d's column (di_d/dt) is zero there.
    assert!(numerical_reason(least_squares(&[flat], 4, MotorKind::Ipm)).contains("`l_d`"));
    // Weights: all zero, negative, wrong length.
    let zero = CustomWeighting::new("zero", |_, _| 0.0);
    let opts = LinearOptions::default();
    assert_eq!(
        option_of(weighted_least_squares(std::slice::from_ref(&a), 4, MotorKind::Spm, &zero, &opts)),
        "weighting"
    );
    let neg = CustomWeighting::new("neg", |_, k| if k == 7 { -1.0 } else { 1.0 });
    assert_eq!(
        option_of(weighted_least_squares(std::slice::from_ref(&a), 4, MotorKind::Spm, &neg, &opts)),
        "weighting"
    );
    assert_eq!(option_of(weighted_least_squares(&[a], 4, MotorKind::Spm, &Short, &opts)), "weighting");
}

/// A weighting that returns one weight too few.
#[derive(Debug)]
struct Short;
impl Weighting for Short {
    fn name(&self) -> String {
        "short".into()
    }
    fn sample_weight(&self, _: &Experiment, _: usize) -> f64 {
        1.0
    }
    fn weights(&self, e: &Experiment) -> Result<Vec<f64>> {
        Ok(vec![1.0; e.len() - 1])
    }
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn display_and_serde() {
    crate::common::require_shared!();
    let (e, t) = load("ipm_moves_idinj");
    let ls = least_squares(&[e], t.n_p, MotorKind::Ipm).unwrap();
    let text = ls.to_string();
    for s in ["r_s", "l_d", "l_q", "k_e", "ohm", "V s/rad", "error index", "std error", "uniform"] {
        assert!(text.contains(s), "missing `{s}` in\n{text}");
    }
    let json = serde_json::to_string(&ls).unwrap();
    let back: LinearEstimate = serde_json::from_str(&json).unwrap();
    assert_eq!(back.theta, ls.theta);
    assert_eq!(back.kind, MotorKind::Ipm);
    let opts: LinearOptions = serde_json::from_str(r#"{"prefilter": 500.0}"#).unwrap();
    assert_eq!(opts, LinearOptions { prefilter: Some(500.0), filter_order: 4 });
}
