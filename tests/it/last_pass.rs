//! The pass a solver expects to be its last (`LeastSquares::normal_equations_likely_last`):
//! both solvers evaluate the point that ends a run by the step or cost test with it
//! (Misra1a), and a prediction-error fit of a drive log ends on such a pass, whose kept
//! sums serve the statistics without another simulation.

use crate::solvers::{CurveFit, MISRA1A, misra1a};
use approx::relative_eq;
use argmin::core::{Executor, State};
use greybox::estimate::LsState;
use greybox::estimate::NormalEquations;
use greybox::estimate::{
    GaussNewton, LeastSquares, LevenbergMarquardt, ReportsTermination, Termination, Tolerances,
};
use nalgebra::DVector;
use std::sync::Mutex;

/// A [`CurveFit`] that records the points of `normal_equations_likely_last`.
struct Flagged {
    inner: CurveFit,
    flagged: Mutex<Vec<Vec<f64>>>,
}

impl LeastSquares for Flagged {
    fn n_params(&self) -> usize {
        self.inner.n_params()
    }
    fn normal_equations(&self, p: &DVector<f64>) -> greybox::Result<NormalEquations> {
        self.inner.normal_equations(p)
    }
    fn normal_equations_likely_last(&self, p: &DVector<f64>) -> greybox::Result<NormalEquations> {
        self.flagged.lock().unwrap().push(p.as_slice().to_vec());
        self.inner.normal_equations(p)
    }
    fn cost(&self, p: &DVector<f64>) -> greybox::Result<f64> {
        self.inner.cost(p)
    }
    fn project(&self, p: &mut DVector<f64>) {
        self.inner.project(p)
    }
}

/// Both solvers evaluate the point that ends a run converged by the step or cost test by
/// `normal_equations_likely_last`, so that a problem can gather its statistics there, and
/// flag at most half their passes; Misra1a from NIST's first start, as measured and with
/// exact data (zero residual at the certified values).
#[test]
fn solvers_flag_the_evaluation_that_ends_the_run() {
    fn check<S>(solver: S, name: &str, exact: bool)
    where
        S: for<'a> argmin::core::Solver<&'a Flagged, LsState> + ReportsTermination,
    {
        let mut inner = misra1a();
        if exact {
            inner.y = inner.x.iter().map(|&x| (inner.f)(&MISRA1A, x).0).collect();
        }
        let problem = Flagged { inner, flagged: Mutex::new(Vec::new()) };
        let res = Executor::new(&problem, solver)
            .configure(|s| s.param(DVector::from_column_slice(&[500.0, 1e-4])).max_iters(200).counting(true))
            .run()
            .expect("solver runs");
        let t = res.solver.termination().cloned();
        let flagged = problem.flagged.lock().unwrap();
        assert!(matches!(t, Some(Termination::StepTolerance | Termination::CostTolerance)), "{name}: {t:?}");
        let p = res.state.get_best_param().expect("estimate").as_slice().to_vec();
        assert!(relative_eq!(p[0], MISRA1A[0], max_relative = 1e-8), "{name}: {p:?}");
        assert_eq!(flagged.last(), Some(&p), "{name}: the last flagged point is the estimate");
        let evaluations = res.state.get_func_counts().get("normal_equations_count").copied().unwrap_or(0);
        assert!(
            (flagged.len() as u64) * 2 <= evaluations,
            "{name}: {} of {evaluations} passes flagged",
            flagged.len()
        );
    }
    // The gradient test needs the new point's gradient: it cannot be foreseen, so it is off.
    let tol = Tolerances { gtol: 0.0, ..Default::default() };
    check(LevenbergMarquardt::new(tol), "lm", false);
    check(LevenbergMarquardt::new(tol), "lm", true);
    // On the noisy data Gauss-Newton ends after a full step that fails at the cost's
    // rounding floor: its estimate is the point before, which no test could foresee.
    check(GaussNewton::new(tol), "gn", true);
}

/// A prediction-error fit of a drive log (SPM, x0 estimated, LM from off the truth and GN
/// from its start) ends on the flagged pass: its statistics at the estimate take every sum
/// from it; a problem that ran only unflagged passes there does not.
#[test]
fn a_drive_log_fit_ends_on_the_flagged_pass() {
    use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
    use greybox::estimate::{NominalScaling, PemProblem, ProblemOptions, RunOptions, SolverKind, run_solver};
    use greybox::model::Prepared;
    use greybox::pmsm::{PmsmSpm, VoltageHold};
    let cfg = DriveConfig { duration: 0.3, ..scenario("exp3", SPM_MOTOR).unwrap() };
    let e = simulate_drive(&cfg).unwrap().experiment;
    let m = PmsmSpm::new(SPM_MOTOR.n_p, VoltageHold::Stator);
    let start = [1.1 * SPM_MOTOR.r_s, 0.9 * SPM_MOTOR.l_d, SPM_MOTOR.k_e()];
    let opts = ProblemOptions { estimate_x0: true, ..Default::default() };
    for solver in [SolverKind::Lm, SolverKind::Gn] {
        let problem =
            PemProblem::new(&m, vec![(Prepared::new(&m, &e).unwrap(), None)], &start, &NominalScaling, &opts)
                .unwrap();
        let run = RunOptions { solver, ..Default::default() };
        let (p, report) = run_solver(&problem, problem.start_vector(&start), &run).unwrap();
        assert!(report.success, "{solver:?}: {}", report.termination);
        assert!(problem.statistics_kept(&p), "{solver:?}: the estimate's pass was not flagged");
        let fresh =
            PemProblem::new(&m, vec![(Prepared::new(&m, &e).unwrap(), None)], &start, &NominalScaling, &opts)
                .unwrap();
        fresh.normal_equations(&p).unwrap();
        assert!(!fresh.statistics_kept(&p), "{solver:?}: an unflagged pass keeps no residual sums");
    }
}
