//! The solvers against known solutions (their agreement on the development logs is
//! `solver_agreement.rs`):
//! - Gauss-Newton on small problems with known solutions: NIST StRD Misra1a (certified
//!   values), a bound-constrained fit (and Levenberg-Marquardt on it), a rank-deficient fit
//!   (diagonal shift), a problem with an infeasible region (failed line-search trials);
//! - the cost never increases across iterations; bad options are errors.

use approx::relative_eq;
use argmin::core::observers::{Observe, ObserverMode};
use argmin::core::{Executor, KV, State};
use greybox::estimate::LsState;
use greybox::estimate::NormalEquations;
use greybox::estimate::{
    GaussNewton, LeastSquares, LevenbergMarquardt, ReportsTermination, Termination, Tolerances, TrustRegion,
};
use nalgebra::{DMatrix, DVector};
use std::sync::{Arc, Mutex};

// ---------------------------------------------------------------------------------------
// Small problems with known solutions

/// Curve fit `ŷ_k = f(p, x_k)` with an analytic gradient, box bounds and an optional
/// region where the "model cannot be simulated".
pub(crate) struct CurveFit {
    pub(crate) x: Vec<f64>,
    pub(crate) y: Vec<f64>,
    /// `(ŷ, ∂ŷ/∂p)` at `x`.
    pub(crate) f: fn(&[f64], f64) -> (f64, Vec<f64>),
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// Points where this returns true are infeasible (`Error::InvalidParameter`).
    infeasible: fn(&[f64]) -> bool,
}

impl CurveFit {
    fn check(&self, p: &DVector<f64>) -> greybox::Result<()> {
        if (self.infeasible)(p.as_slice()) {
            return Err(greybox::Error::InvalidParameter {
                name: "p".into(),
                value: p[0],
                reason: "outside the model's domain".into(),
            });
        }
        Ok(())
    }
}

impl LeastSquares for CurveFit {
    fn n_params(&self) -> usize {
        self.lower.len()
    }
    fn normal_equations(&self, p: &DVector<f64>) -> greybox::Result<NormalEquations> {
        self.check(p)?;
        let n = self.n_params();
        let (mut cost, mut jtj, mut jtr) = (0.0, DMatrix::zeros(n, n), DVector::zeros(n));
        for (&x, &y) in self.x.iter().zip(&self.y) {
            let (yhat, j) = (self.f)(p.as_slice(), x);
            let j = DVector::from_vec(j);
            let e = y - yhat;
            cost += 0.5 * e * e;
            jtr += &j * e;
            jtj += &j * j.transpose();
        }
        Ok(NormalEquations { cost, jtj: jtj.into(), jtr })
    }
    fn cost(&self, p: &DVector<f64>) -> greybox::Result<f64> {
        self.check(p)?;
        Ok(self.x.iter().zip(&self.y).map(|(&x, &y)| 0.5 * (y - (self.f)(p.as_slice(), x).0).powi(2)).sum())
    }
    fn project(&self, p: &mut DVector<f64>) {
        for j in 0..p.len() {
            p[j] = p[j].clamp(self.lower[j], self.upper[j]);
        }
    }
}

/// NIST StRD Misra1a (https://www.itl.nist.gov/div898/strd/nls/data/misra1a.shtml):
/// `y = b1 (1 − exp(−b2 x))`, 14 observations.
pub(crate) fn misra1a() -> CurveFit {
    CurveFit {
        x: vec![
            77.6, 114.9, 141.1, 190.8, 239.9, 289.0, 332.8, 378.4, 434.8, 477.3, 536.8, 593.1, 689.1, 760.0,
        ],
        y: vec![
            10.07, 14.73, 17.94, 23.93, 29.61, 35.18, 40.02, 44.82, 50.76, 55.05, 61.01, 66.40, 75.47, 81.78,
        ],
        f: |p, x| {
            let e = (-p[1] * x).exp();
            (p[0] * (1.0 - e), vec![1.0 - e, p[0] * x * e])
        },
        lower: vec![f64::NEG_INFINITY; 2],
        upper: vec![f64::INFINITY; 2],
        infeasible: |_| false,
    }
}

/// Certified values of Misra1a: b1, b2 and the residual sum of squares `2V`.
pub(crate) const MISRA1A: [f64; 2] = [2.389_421_291_8e2, 5.501_564_318_1e-4];
const MISRA1A_RSS: f64 = 1.245_513_889_4e-1;

/// One iteration as an observer sees it.
#[derive(Clone, Debug)]
struct Record {
    cost: f64,
    param: Vec<f64>,
    accepted: Option<bool>,
    shift: Option<f64>,
    held: Option<u64>,
    trials: Option<u64>,
}

#[derive(Clone, Default)]
struct Recorder(Arc<Mutex<Vec<Record>>>);

impl Recorder {
    fn push(&self, state: &LsState, kv: &KV) -> Result<(), argmin::core::Error> {
        let param = state.get_param().map(|p| p.as_slice().to_vec()).unwrap_or_default();
        self.0.lock().map_err(|e| argmin::core::Error::msg(e.to_string()))?.push(Record {
            cost: state.get_cost(),
            param,
            accepted: kv.get("accepted").and_then(|v| v.get_bool()),
            shift: kv.get("shift").and_then(|v| v.get_float()),
            held: kv.get("held").and_then(|v| v.get_uint()),
            trials: kv.get("trials").and_then(|v| v.get_uint()),
        });
        Ok(())
    }
    fn records(&self) -> Vec<Record> {
        self.0.lock().expect("recorder lock").clone()
    }
}

impl Observe<LsState> for Recorder {
    fn observe_init(&mut self, _name: &str, state: &LsState, kv: &KV) -> Result<(), argmin::core::Error> {
        self.push(state, kv)
    }
    fn observe_iter(&mut self, state: &LsState, kv: &KV) -> Result<(), argmin::core::Error> {
        self.push(state, kv)
    }
}

struct Run {
    p: Vec<f64>,
    cost: f64,
    termination: Termination,
    records: Vec<Record>,
}

fn run<S>(problem: &CurveFit, solver: S, p0: &[f64]) -> Run
where
    S: for<'a> argmin::core::Solver<&'a CurveFit, LsState> + ReportsTermination,
{
    let recorder = Recorder::default();
    let res = Executor::new(problem, solver)
        .configure(|s| s.param(DVector::from_column_slice(p0)).max_iters(200))
        .add_observer(recorder.clone(), ObserverMode::Always)
        .run()
        .expect("solver runs");
    let termination = res.solver.termination().cloned().unwrap_or(Termination::MaxIterations);
    let p = res.state.get_best_param().expect("estimate").as_slice().to_vec();
    Run { p, cost: res.state.get_best_cost(), termination, records: recorder.records() }
}

fn assert_monotone(records: &[Record]) {
    for w in records.windows(2) {
        assert!(w[1].cost <= w[0].cost, "cost increased from {:e} to {:e}", w[0].cost, w[1].cost);
        if w[1].accepted == Some(true) {
            assert!(w[1].cost < w[0].cost, "an accepted step must lower the cost");
        }
    }
}

#[test]
fn gn_recovers_misra1a_certified_values_from_both_nist_starts() {
    let problem = misra1a();
    for start in [[500.0, 1e-4], [250.0, 5e-4]] {
        let r = run(&problem, GaussNewton::new(Tolerances::default()), &start);
        eprintln!(
            "Misra1a from {start:?}: {:?} after {} iterations: {:?}",
            r.termination,
            r.records.len() - 1,
            r.p
        );
        assert!(r.termination.success(), "{:?}", r.termination);
        // The certified values have 11 significant digits.
        assert!(relative_eq!(r.p[0], MISRA1A[0], max_relative = 1e-9), "b1 = {:.12e}", r.p[0]);
        assert!(relative_eq!(r.p[1], MISRA1A[1], max_relative = 1e-9), "b2 = {:.12e}", r.p[1]);
        assert!(relative_eq!(2.0 * r.cost, MISRA1A_RSS, max_relative = 1e-9), "RSS = {:.12e}", 2.0 * r.cost);
        // Along Misra1a's valley (b1, b2 correlated) the cost is flat to rounding over a few
        // 1e-10 relative: the solvers stop at different points of that flat stretch.
        let lm = run(&problem, LevenbergMarquardt::new(Tolerances::default()), &start);
        for j in 0..2 {
            assert!(relative_eq!(r.p[j], lm.p[j], max_relative = 2e-9), "GN {:?} vs LM {:?}", r.p, lm.p);
        }
    }
}

#[test]
fn gn_never_increases_the_cost() {
    let problem = misra1a();
    // The far NIST start needs the line search.
    let r = run(&problem, GaussNewton::new(Tolerances::default()), &[500.0, 1e-4]);
    assert!(r.records.len() > 2);
    assert_monotone(&r.records);
    // Iteration records (not the initial one) carry the line-search keys.
    for rec in &r.records[1..] {
        assert!(rec.accepted.is_some() && rec.shift.is_some() && rec.trials.is_some(), "{rec:?}");
        assert_eq!(rec.held, Some(0), "no bounds, nothing held");
    }
}

/// Misra1a in scaled variables `p = (b1 / 100, 1000 b2)` (the solvers' step tolerance is
/// relative to ‖p‖, so the variables must be of comparable size, as in a `PemProblem`),
/// with b1 ≤ 200, which cuts off the unconstrained minimum (b1 ≈ 238.9): a fit ends on
/// the bound, along which b1 and b2 are strongly correlated.
fn bounded_misra1a() -> CurveFit {
    let mut problem = misra1a();
    problem.f = |p, x| {
        let e = (-p[1] * 1e-3 * x).exp();
        (100.0 * p[0] * (1.0 - e), vec![100.0 * (1.0 - e), 0.1 * p[0] * x * e])
    };
    problem.upper[0] = 2.0;
    problem
}

/// A run `r` of [`bounded_misra1a`] ended at the bounded minimum: converged, on the bound,
/// stationary in b2 with the bound active, and holding b1 there in its last iteration.
fn assert_bounded_minimum(problem: &CurveFit, r: &Run) {
    assert!(r.termination.success(), "{:?}", r.termination);
    assert_eq!(r.p[0], 2.0);
    assert_monotone(&r.records);
    // On the bound the remaining one-parameter problem in b2 is stationary, and the
    // bound is active: the unconstrained descent direction points out of the box.
    let ne = problem.normal_equations(&DVector::from_column_slice(&r.p)).expect("feasible");
    let cosine = ne.jtr[1].abs() / (ne.jtj[(1, 1)].sqrt() * (2.0 * ne.cost).sqrt());
    assert!(cosine < 1e-7, "cosine {cosine:e}");
    assert!(ne.jtr[0] > 0.0);
    assert!(r.records.last().and_then(|rec| rec.held).is_some_and(|h| h == 1), "{:?}", r.records.last());
}

#[test]
fn gn_respects_bounds() {
    let problem = bounded_misra1a();
    let r = run(&problem, GaussNewton::new(Tolerances::default()), &[1.5, 1.0]);
    eprintln!("bounded Misra1a: {:?}, {:?}", r.termination, r.p);
    assert_bounded_minimum(&problem, &r);
}

/// Levenberg-Marquardt holds a parameter pressed against its bound and solves for the
/// others (the active set of `estimate::solver::active`): it reaches the bounded minimum
/// in a few iterations. Projecting the unbounded step instead moved b2 by the part of a
/// step the bound forbids, and crawled along the bound.
#[test]
fn lm_respects_bounds_without_crawling() {
    let problem = bounded_misra1a();
    for start in [[1.5, 1.0], [1.9, 0.3]] {
        let r = run(&problem, LevenbergMarquardt::new(Tolerances::default()), &start);
        eprintln!(
            "bounded Misra1a by LM from {start:?}: {:?} after {} iterations, {:?}",
            r.termination,
            r.records.len() - 1,
            r.p
        );
        assert_bounded_minimum(&problem, &r);
        assert!(r.records.len() - 1 <= 20, "{} iterations", r.records.len() - 1);
    }
}

/// MINPACK's trust region (`TrustRegion`) on the same bounded problem, through the same
/// active set: the bounded minimum in a few iterations, the cost never rising; and
/// Misra1a's certified values from both NIST starts unbounded.
#[test]
fn trust_region_respects_bounds_and_recovers_misra1a() {
    let problem = bounded_misra1a();
    for start in [[1.5, 1.0], [1.9, 0.3]] {
        let r = run(&problem, TrustRegion::new(Tolerances::default()), &start);
        eprintln!(
            "bounded Misra1a by the trust region from {start:?}: {:?} after {} iterations",
            r.termination,
            r.records.len() - 1
        );
        assert_bounded_minimum(&problem, &r);
        assert!(r.records.len() - 1 <= 20, "{} iterations", r.records.len() - 1);
    }
    let problem = misra1a();
    for start in [[500.0, 1e-4], [250.0, 5e-4]] {
        let r = run(&problem, TrustRegion::new(Tolerances::default()), &start);
        assert!(r.termination.success(), "{:?}", r.termination);
        assert_monotone(&r.records);
        for (p, c) in r.p.iter().zip(MISRA1A) {
            assert!((p / c - 1.0).abs() < 1e-6, "{:?} against {MISRA1A:?}", r.p);
        }
    }
}

#[test]
fn gn_shifts_a_singular_information_matrix() {
    // ŷ = (a + b) x: only a + b is determined, JᵀWJ is exactly singular (Σx² = 9).
    let problem = CurveFit {
        x: vec![1.0, 2.0, 2.0],
        y: vec![2.1, 3.9, 4.2],
        f: |p, x| ((p[0] + p[1]) * x, vec![x, x]),
        lower: vec![f64::NEG_INFINITY; 2],
        upper: vec![f64::INFINITY; 2],
        infeasible: |_| false,
    };
    let r = run(&problem, GaussNewton::new(Tolerances::default()), &[0.0, 1.0]);
    eprintln!("singular: {:?}, {:?}", r.termination, r.p);
    assert!(r.termination.success(), "{:?}", r.termination);
    let sum_xy = 2.1 + 2.0 * 3.9 + 2.0 * 4.2;
    assert!(relative_eq!(r.p[0] + r.p[1], sum_xy / 9.0, max_relative = 1e-10), "a + b = {}", r.p[0] + r.p[1]);
    assert!(r.records[1].shift.is_some_and(|s| s > 0.0), "the KV reports the shift: {:?}", r.records[1]);
    assert_monotone(&r.records);
}

#[test]
fn gn_treats_infeasible_trials_as_failed() {
    // ŷ = p fitted to a mean of 10 from p = 0, with p > 6 unusable: the full step to 10
    // fails, the halved one (p = 5) is accepted; the fit never leaves the usable region.
    let problem = CurveFit {
        x: vec![0.0; 4],
        y: vec![9.0, 11.0, 9.5, 10.5],
        f: |p, _| (p[0], vec![1.0]),
        lower: vec![f64::NEG_INFINITY],
        upper: vec![f64::INFINITY],
        infeasible: |p| p[0] > 6.0,
    };
    let r = run(&problem, GaussNewton::new(Tolerances::default()), &[0.0]);
    eprintln!("infeasible region: {:?}, {:?} after {} iterations", r.termination, r.p, r.records.len() - 1);
    let first = &r.records[1];
    assert_eq!(first.trials, Some(2), "{first:?}");
    assert_eq!(first.accepted, Some(true));
    assert_eq!(first.param, vec![5.0]);
    assert!(r.p[0] <= 6.0 && r.p[0] > 5.9, "{:?}", r.p);
    assert_monotone(&r.records);
}

#[test]
fn gn_rejects_bad_options() {
    let gn = || GaussNewton::new(Tolerances::default());
    for c1 in [0.0, 1.0, -0.5, 2.0, f64::NAN] {
        assert!(gn().with_c1(c1).is_err(), "c1 = {c1}");
    }
    for factor in [0.0, 1.0, 1.5, -0.1, f64::INFINITY] {
        assert!(gn().with_backtracking_factor(factor).is_err(), "factor = {factor}");
    }
    for alpha in [0.0, -1e-3, 2.0, f64::NAN] {
        assert!(gn().with_min_alpha(alpha).is_err(), "alpha = {alpha}");
    }
    let ok =
        gn().with_c1(0.1).and_then(|g| g.with_backtracking_factor(0.3)).and_then(|g| g.with_min_alpha(1e-12));
    assert!(ok.is_ok());
    let err = gn().with_c1(0.0).unwrap_err().to_string();
    assert!(err.contains("c1"), "{err}");
}

#[test]
fn gn_with_custom_line_search_still_recovers_misra1a() {
    let solver = GaussNewton::new(Tolerances::default())
        .with_c1(0.3)
        .and_then(|g| g.with_backtracking_factor(0.1))
        .expect("valid options");
    let r = run(&misra1a(), solver, &[500.0, 1e-4]);
    assert!(r.termination.success(), "{:?}", r.termination);
    assert!(
        relative_eq!(r.p[0], MISRA1A[0], max_relative = 1e-9)
            && relative_eq!(r.p[1], MISRA1A[1], max_relative = 1e-9),
        "{:?}",
        r.p
    );
    assert_monotone(&r.records);
}

/// Determinism: an IPM fit (least-squares start by QR, then LM) and an SPM fit give
/// bit-identical reports on 1 and 2 threads (timings aside).
#[test]
fn fits_are_bit_identical_for_any_thread_count() {
    use greybox::pmsm::{MotorKind, PmsmFitOptions, PmsmIpm, VoltageHold, fit_pmsm};
    let mut rng = crate::common::Rng(11);
    let s = crate::common::exciting_signals(20_000, 1e-4, 200.0, 40.0, 0.4, &mut rng);
    let ipm = crate::common::simulate_into(
        &PmsmIpm::new(2, VoltageHold::Stator),
        &[0.35, 3.2e-3, 7.5e-3, 0.4164],
        1e-4,
        s.clone(),
    );
    let spm = crate::common::simulate_into(
        &greybox::pmsm::PmsmSpm::new(2, VoltageHold::Stator),
        &[0.35, 3.2e-3, 0.4164],
        1e-4,
        s,
    );
    for (model, e) in [(MotorKind::Ipm, ipm), (MotorKind::Spm, spm)] {
        let options = PmsmFitOptions { model, ..crate::common::pmsm_options(2) };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let fit = pool.install(|| fit_pmsm(std::slice::from_ref(&e), &options)).unwrap();
            let mut json: serde_json::Value = serde_json::from_str(&fit.to_json()).unwrap();
            json["timing"] = serde_json::Value::Null;
            json.to_string()
        };
        assert_eq!(run(1), run(2), "{model:?}");
    }
}
