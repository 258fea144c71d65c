//! The fit's early end: Levenberg-Marquardt from the linear least-squares start with a
//! close start's damping (`CLOSE_START_DAMPING`), ending where the next step would move
//! the point by less than xtol and lower the cost by less than ftol. It must give the
//! estimate of a run held to far tighter tolerances, within what xtol allows, in fewer
//! passes than the old defaults; and a bad damping is refused by name.

use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
use greybox::estimate::{DEFAULT_DAMPING, PemOptions, Tolerances};
use greybox::pmsm::{HoldChoice, MotorKind, PmsmFit, PmsmFitOptions, fit_pmsm};
use greybox::{Error, Experiment};

/// Two seconds of the exp3 moves with `sigma` \[A\] of current noise (the loss at the
/// minimum is far from zero, so the early end may apply).
fn noisy_log(sigma: f64) -> Experiment {
    let mut cfg = DriveConfig { duration: 2.0, ..scenario("exp3", SPM_MOTOR).unwrap() };
    cfg.sensors.current_noise = sigma;
    simulate_drive(&cfg).unwrap().experiment
}

fn fit(e: &Experiment, pem: PemOptions) -> PmsmFit {
    let o = PmsmFitOptions {
        model: MotorKind::Spm,
        hold: HoldChoice::Stator,
        pem,
        ..PmsmFitOptions::new(SPM_MOTOR.n_p)
    };
    fit_pmsm(std::slice::from_ref(e), &o).unwrap()
}

/// Fits `e` with the defaults, with tight tolerances and with the old initial damping;
/// checks the first against the second; returns the passes of the three.
fn compare(e: &Experiment) -> (u64, u64, u64) {
    let quick = fit(e, PemOptions::default());
    let tight_tol = Tolerances { ftol: 1e-15, xtol: 1e-15, gtol: 1e-15, max_iters: 200 };
    let tight = fit(e, PemOptions { tolerances: tight_tol, ..Default::default() });
    let old = fit(e, PemOptions { initial_damping: Some(DEFAULT_DAMPING), ..Default::default() });
    assert!(quick.report.solver.success, "{}", quick.report.solver.termination);
    for (a, b) in quick.report.parameters.iter().zip(&tight.report.parameters) {
        // xtol = 1e-10 bounds the step left untaken in the scaled norm.
        let rel = (a.value - b.value).abs() / b.value.abs();
        assert!(rel < 1e-9, "{}: {} vs {} ({rel:.1e})", a.name, a.value, b.value);
        assert!(
            (a.value - b.value).abs() < 1e-6 * b.std_error,
            "{}: moved {:.1e} standard errors",
            a.name,
            (a.value - b.value).abs() / b.std_error
        );
        let se = (a.std_error - b.std_error).abs() / b.std_error;
        assert!(se < 1e-6, "{}: standard error {} vs {} ({se:.1e})", a.name, a.std_error, b.std_error);
    }
    (quick.report.solver.evaluations, tight.report.solver.evaluations, old.report.solver.evaluations)
}

#[test]
fn the_early_end_gives_the_tight_estimate_in_no_more_passes() {
    // 20 mA: the run ends on ftol before the early end can; 0.2 mA: the early end saves
    // passes.
    let (q, t, o) = compare(&noisy_log(0.02));
    assert!(q <= o && q < t, "20 mA, passes: early end {q}, tight {t}, old damping {o}");
    let (q, t, o) = compare(&noisy_log(2e-4));
    assert!(q < o && q < t, "0.2 mA, passes: early end {q}, tight {t}, old damping {o}");
}

#[test]
fn a_bad_initial_damping_is_refused_by_name() {
    let e = noisy_log(0.02);
    for bad in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        let o = PmsmFitOptions {
            hold: HoldChoice::Stator,
            pem: PemOptions { initial_damping: Some(bad), ..Default::default() },
            ..PmsmFitOptions::new(SPM_MOTOR.n_p)
        };
        match fit_pmsm(std::slice::from_ref(&e), &o) {
            Err(Error::InvalidOption { option, .. }) => assert_eq!(option, "initial_damping", "{bad}"),
            other => panic!("{bad}: {other:?}"),
        }
    }
}
