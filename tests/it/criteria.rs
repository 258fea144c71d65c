//! Criteria and options of the prediction-error fit on simulated records: k-step-ahead
//! prediction, residual prefilter, parameter scalings, initial-state estimation, the
//! finite-difference fallback for models without analytic sensitivities, and determinism
//! of multi-experiment fits.

use crate::common::{Rng, exciting_signals, rel, sim, simulate_into};
use approx::relative_eq;
use greybox::estimate::{NominalScaling, PemOptions, PemProblem, ProblemOptions, ScalingKind, fit};
use greybox::model::{GreyBoxModel, Parameter, Prepared, Signal};
use greybox::pmsm::{DqView, PmsmIpm, PmsmSpm, VoltageHold};
use greybox::{Experiment, Result};

const THETA: [f64; 3] = [0.9, 4.5e-3, 0.539];

fn record(seed: u64, n: usize) -> Experiment {
    let h = 1e-4;
    let mut rng = Rng(seed);
    simulate_into(
        &PmsmSpm::new(4, VoltageHold::Stator),
        &THETA,
        h,
        exciting_signals(n, h, 250.0, 60.0, THETA[2], &mut rng),
    )
}

fn assert_recovers(opts: &PemOptions, start: &[f64], tol: f64, label: &str) {
    let e = record(3, 4000);
    let r = fit(&PmsmSpm::new(4, VoltageHold::Stator), &[e], start, opts).unwrap();
    assert!(r.solver.success, "{label}: {}", r.solver.termination);
    for (n, t) in ["r_s", "l_s", "k_e"].iter().zip(THETA) {
        let v = r.parameter(n).unwrap().value;
        assert!(relative_eq!(v, t, max_relative = tol), "{label}: {n} = {v} vs {t}");
    }
}

const START: [f64; 3] = [1.3, 3.0e-3, 0.6];

#[test]
fn k_step_prediction_recovers_noise_free_parameters() {
    for k in [1, 5, 50] {
        assert_recovers(
            &PemOptions { horizon: Some(k), ..Default::default() },
            &START,
            1e-8,
            &format!("horizon {k}"),
        );
    }
}

#[test]
fn residual_prefilter_recovers_noise_free_parameters() {
    assert_recovers(
        &PemOptions { prefilter: Some(800.0), ..Default::default() },
        &START,
        1e-8,
        "prefilter 800 Hz",
    );
}

#[test]
fn every_scaling_reaches_the_same_estimate() {
    for s in [ScalingKind::Nominal, ScalingKind::Log, ScalingKind::ColumnNorm, ScalingKind::Identity] {
        assert_recovers(&PemOptions { scaling: s, ..Default::default() }, &START, 1e-8, &format!("{s:?}"));
    }
}

#[test]
fn initial_state_is_estimated_when_the_first_sample_is_wrong() {
    // Corrupt the first current sample by 1 A. Taken as the exact initial state, it biases
    // the parameters; estimated, it is one residual among 8000 and x0 comes back close to
    // the true first state.
    let e = record(4, 4000);
    let v = DqView::try_new(&e).unwrap();
    let true_first = [v.i_d()[0], v.i_q()[0]];
    let mut s = v.to_signals();
    s.i_d[0] += 1.0;
    s.i_q[0] -= 1.0;
    let bad = s.into_experiment("bad-first", e.h()).unwrap();
    let m = PmsmSpm::new(4, VoltageHold::Stator);
    let worst = |r: &greybox::estimate::FitResult| {
        ["r_s", "l_s", "k_e"]
            .iter()
            .zip(THETA)
            .map(|(n, t)| rel(r.parameter(n).unwrap().value, t))
            .fold(0.0, f64::max)
    };
    let est = fit(&m, std::slice::from_ref(&bad), &START, &PemOptions::default()).unwrap();
    let fixed = fit(&m, &[bad], &START, &PemOptions { estimate_x0: false, ..Default::default() }).unwrap();
    assert!(fixed.initial_states.is_empty());
    let x0_error: f64 =
        est.initial_states.iter().zip(true_first).map(|(p, t)| (p.value - t).abs()).fold(0.0, f64::max);
    eprintln!(
        "worst relative error: x0 estimated {:.2e}, x0 fixed {:.2e}; x0 error {x0_error:.2e} A",
        worst(&est),
        worst(&fixed)
    );
    assert!(worst(&fixed) > 1e-4, "a wrong fixed x0 should bias the fit: {:e}", worst(&fixed));
    assert!(worst(&est) < worst(&fixed) / 20.0, "estimated {:e} vs fixed {:e}", worst(&est), worst(&fixed));
    assert!(x0_error < 0.1, "x0 off by {x0_error} A");
}

/// A model that hides its analytic sensitivities, so the estimator falls back to finite
/// differences of the step.
struct NoSensitivities<M>(M);

impl<M: GreyBoxModel> GreyBoxModel for NoSensitivities<M> {
    type Inputs = M::Inputs;
    type Coefficients = M::Coefficients;
    fn name(&self) -> &str {
        "no_sensitivities"
    }
    fn n_states(&self) -> usize {
        self.0.n_states()
    }
    fn outputs(&self) -> Vec<Signal> {
        self.0.outputs()
    }
    fn input_channels(&self) -> Vec<String> {
        self.0.input_channels()
    }
    fn states(&self) -> Vec<Signal> {
        self.0.states()
    }
    fn initial_state(&self, y0: &[f64], x0: &mut [f64]) {
        self.0.initial_state(y0, x0)
    }
    fn parameters(&self) -> &[Parameter] {
        self.0.parameters()
    }
    fn prepare(&self, e: &Experiment) -> Result<M::Inputs> {
        self.0.prepare(e)
    }
    fn coefficients(&self, theta: &[f64], inputs: &M::Inputs) -> Result<M::Coefficients> {
        self.0.coefficients(theta, inputs)
    }
    fn step(&self, c: &M::Coefficients, inputs: &M::Inputs, k: usize, x: &[f64], xn: &mut [f64]) {
        self.0.step(c, inputs, k, x, xn)
    }
    fn output(&self, c: &M::Coefficients, inputs: &M::Inputs, k: usize, x: &[f64], y: &mut [f64]) {
        self.0.output(c, inputs, k, x, y)
    }
    // `sensitivities` keeps its default, `None`: the estimator uses finite differences.
}

fn normal_equations<M: GreyBoxModel>(
    m: &M,
    e: &Experiment,
    theta: &[f64],
    x0: bool,
) -> (nalgebra::DMatrix<f64>, nalgebra::DVector<f64>) {
    let prep = Prepared::new(m, e).unwrap();
    let opts = ProblemOptions { estimate_x0: x0, ..Default::default() };
    let p = PemProblem::new(m, vec![(prep, None)], theta, &NominalScaling, &opts).unwrap();
    let ne = p.normal_equations(&p.start_vector(theta)).unwrap();
    (ne.jtj.to_dense(), ne.jtr)
}

#[test]
fn finite_difference_fallback_matches_analytic_sensitivities() {
    let e = record(8, 1500);
    let theta = [1.1, 4.0e-3, 0.55];
    for x0 in [false, true] {
        let (a_jtj, a_jtr) = normal_equations(&PmsmSpm::new(4, VoltageHold::Stator), &e, &theta, x0);
        let (f_jtj, f_jtr) =
            normal_equations(&NoSensitivities(PmsmSpm::new(4, VoltageHold::Stator)), &e, &theta, x0);
        let dj = (&a_jtj - &f_jtj).norm() / a_jtj.norm();
        let dr = (&a_jtr - &f_jtr).norm() / a_jtr.norm();
        eprintln!("x0 {x0}: JᵀJ {dj:.2e}, Jᵀε {dr:.2e}");
        assert!(dj < 1e-6 && dr < 1e-6, "x0 {x0}: JᵀJ {dj:e}, Jᵀε {dr:e}");
    }
    let h = 2e-4;
    let mut rng = Rng(9);
    let th = [0.35, 3.2e-3, 7.5e-3, 0.4164];
    let ipm = PmsmIpm::new(2, VoltageHold::Stator);
    let e = simulate_into(&ipm, &th, h, exciting_signals(1500, h, 200.0, 40.0, th[3], &mut rng));
    let start = [0.4, 3.0e-3, 7.0e-3, 0.4];
    let (a_jtj, a_jtr) = normal_equations(&ipm, &e, &start, true);
    let (f_jtj, f_jtr) =
        normal_equations(&NoSensitivities(PmsmIpm::new(2, VoltageHold::Stator)), &e, &start, true);
    let dj = (&a_jtj - &f_jtj).norm() / a_jtj.norm();
    let dr = (&a_jtr - &f_jtr).norm() / a_jtr.norm();
    eprintln!("IPM: JᵀJ {dj:.2e}, Jᵀε {dr:.2e}");
    assert!(dj < 1e-6 && dr < 1e-6, "IPM: JᵀJ {dj:e}, Jᵀε {dr:e}");
}

#[test]
fn multi_experiment_results_do_not_depend_on_the_thread_count() {
    let logs = [record(21, 3000), record(22, 3000), record(23, 3000)];
    let opts = PemOptions { per_experiment: vec!["r_s".into()], ..Default::default() };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| fit(&PmsmSpm::new(4, VoltageHold::Stator), &logs, &START, &opts).unwrap())
    };
    let (one, four) = (run(1), run(4));
    for (a, b) in one.parameters.iter().zip(&four.parameters) {
        assert_eq!(a.value.to_bits(), b.value.to_bits(), "{}", a.name);
        assert_eq!(a.std_error.to_bits(), b.std_error.to_bits(), "{}", a.name);
    }
}

#[test]
fn full_residuals_and_jacobian_agree_with_the_streamed_normal_equations() {
    let e = record(31, 1200);
    let m = PmsmSpm::new(4, VoltageHold::Stator);
    let start = [1.1, 4.0e-3, 0.55];
    for x0 in [false, true] {
        let prep = Prepared::new(&m, &e).unwrap();
        let opts = ProblemOptions { estimate_x0: x0, ..Default::default() };
        let p = PemProblem::new(&m, vec![(prep, None)], &start, &NominalScaling, &opts).unwrap();
        let p0 = p.start_vector(&start);
        let ne = p.normal_equations(&p0).unwrap();
        let (r, j) = p.residuals_and_jacobian(&p0).unwrap();
        let jtj = j.transpose() * &j;
        let jtr = j.transpose() * &r;
        let ne_jtj = ne.jtj.to_dense();
        assert!((&jtj - &ne_jtj).norm() / ne_jtj.norm() < 1e-12, "x0 {x0}");
        assert!((&jtr - &ne.jtr).norm() / ne.jtr.norm() < 1e-12, "x0 {x0}");
        assert!((0.5 * r.norm_squared() - ne.cost).abs() / ne.cost < 1e-12, "x0 {x0}");
    }
}

#[test]
fn wrong_parameter_count_is_an_error_not_a_panic() {
    let e = record(32, 100);
    let m = PmsmSpm::new(4, VoltageHold::Stator);
    let prep = Prepared::new(&m, &e).unwrap();
    let err = sim(&m, &prep, &[0.9, 4.5e-3]).unwrap_err();
    assert!(err.to_string().contains("theta"), "{err}");
    let err = fit(&m, &[e], &[0.9], &PemOptions::default()).unwrap_err();
    assert!(err.to_string().contains("start"), "{err}");
}
