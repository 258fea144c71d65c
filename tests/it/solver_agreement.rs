//! Gauss-Newton and Levenberg-Marquardt agree to 1e-8 relative on every development log in
//! ../shared/data (same options, least-squares start, automatic voltage hold).

use crate::common::{load, pmsm_options};
use greybox::estimate::{PemOptions, SolverKind};
use greybox::pmsm::{MotorKind, PmsmFit, PmsmFitOptions, fit_pmsm};

// ---------------------------------------------------------------------------------------
// LM against GN on the development logs

fn fit(stem: &str, solver: SolverKind) -> PmsmFit {
    let (e, t) = load(stem);
    let model = if t.salient { MotorKind::Ipm } else { MotorKind::Spm };
    let options =
        PmsmFitOptions { model, pem: PemOptions { solver, ..Default::default() }, ..pmsm_options(t.n_p) };
    fit_pmsm(&[e], &options).expect("fit runs")
}

fn assert_lm_gn_agree(stem: &str) {
    let lm = fit(stem, SolverKind::Lm);
    let gn = fit(stem, SolverKind::Gn);
    assert_eq!(lm.solver.name, "lm");
    assert_eq!(gn.solver.name, "gn");
    assert!(lm.solver.success, "{stem} lm: {}", lm.solver.termination);
    assert!(gn.solver.success, "{stem} gn: {}", gn.solver.termination);
    assert_eq!(lm.hold, gn.hold, "{stem}: both solvers pick the same voltage hold");
    assert_eq!(lm.parameters.len(), gn.parameters.len());
    let mut max_rel: f64 = 0.0;
    for (a, b) in lm.parameters.iter().zip(&gn.parameters) {
        assert_eq!(a.name, b.name);
        let rel = (a.value - b.value).abs() / a.value.abs().max(b.value.abs());
        eprintln!(
            "{stem} {}: lm {:.15e}, gn {:.15e}, relative difference {rel:.3e}",
            a.name, a.value, b.value
        );
        max_rel = max_rel.max(rel);
    }
    eprintln!(
        "{stem}: max relative LM-GN difference {max_rel:.3e}; lm {} iterations, {} evaluations ({}); \
         gn {} iterations, {} evaluations ({}); loss lm {:.12e}, gn {:.12e}",
        lm.solver.iterations,
        lm.solver.evaluations,
        lm.solver.termination,
        gn.solver.iterations,
        gn.solver.evaluations,
        gn.solver.termination,
        lm.fit.loss,
        gn.fit.loss
    );
    assert!(max_rel <= 1e-8, "{stem}: LM and GN differ by {max_rel:e} relative");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn lm_gn_agree_servo_spm_moves() {
    crate::common::require_shared!();
    assert_lm_gn_agree("servo_spm_moves");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn lm_gn_agree_servo_spm_moves_idinj() {
    crate::common::require_shared!();
    assert_lm_gn_agree("servo_spm_moves_idinj");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn lm_gn_agree_servo_spm_moves_idinj_noisy() {
    crate::common::require_shared!();
    assert_lm_gn_agree("servo_spm_moves_idinj_noisy");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn lm_gn_agree_servo_spm_pwm_deadtime_idinj() {
    crate::common::require_shared!();
    assert_lm_gn_agree("servo_spm_pwm_deadtime_idinj");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn lm_gn_agree_ipm_moves_idinj() {
    crate::common::require_shared!();
    assert_lm_gn_agree("ipm_moves_idinj");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn lm_gn_agree_gem_spm_moves_idinj() {
    crate::common::require_shared!();
    assert_lm_gn_agree("gem_spm_moves_idinj");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn lm_gn_agree_gem_ipm_moves_idinj() {
    crate::common::require_shared!();
    assert_lm_gn_agree("gem_ipm_moves_idinj");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn lm_gn_agree_gem_ipm_moves_idinj_noisy() {
    crate::common::require_shared!();
    assert_lm_gn_agree("gem_ipm_moves_idinj_noisy");
}
