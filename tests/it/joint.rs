//! Joint fits of many logs kept by the arrowhead structure of `JᵀWJ`
//! (`estimate::arrowhead`): the structured solve and covariance against dense algebra on
//! random arrowhead systems (exactness), a mid-size joint fit (30 logs, per-log R_s and
//! initial states: 92 free parameters) structured and dense to ~1e-10, recovery of the
//! shared K_e and the per-log R_s from noisy logs, and a singular block named.

use crate::common::{Rng, exciting_signals, experiment, sim};
use greybox::Experiment;
use greybox::estimate::{ArrowLayout, Arrowhead, Singular};
use greybox::estimate::{CovarianceMethod, FitResult, PemOptions, SolverKind, fit};
use greybox::model::Prepared;
use greybox::pmsm::{PmsmSpm, VoltageHold};
use nalgebra::DVector;
use std::sync::Arc;

/// A random positive definite arrowhead matrix: a sum of outer products of rows that touch
/// the shared columns and one block's, as a joint fit's Jacobian rows do. Block b has
/// `1 + b % 3` columns, interleaved with the shared ones in the column order.
fn random_arrowhead(blocks: usize, shared: usize, rng: &mut Rng) -> Arrowhead {
    let mut owner = Vec::new();
    for b in 0..blocks {
        owner.extend(std::iter::repeat_n(Some(b), 1 + b % 3));
        if b % 7 == 0 && owner.iter().filter(|o| o.is_none()).count() < shared {
            owner.push(None);
        }
    }
    while owner.iter().filter(|o| o.is_none()).count() < shared {
        owner.push(None);
    }
    let layout = Arc::new(ArrowLayout::try_new(owner, blocks).unwrap());
    let mut a = Arrowhead::zeros(Arc::clone(&layout));
    for b in 0..blocks {
        let cols: Vec<usize> = layout.block(b).iter().chain(layout.shared()).copied().collect();
        for _ in 0..cols.len() + 3 {
            let row: Vec<f64> = cols.iter().map(|_| rng.normal()).collect();
            for (x, &g) in cols.iter().enumerate() {
                for (y, &h) in cols.iter().enumerate().skip(x) {
                    a.add_symmetric(g, h, row[x] * row[y]);
                }
            }
        }
    }
    a
}

fn rel_diff(a: &DVector<f64>, b: &DVector<f64>) -> f64 {
    (a - b).norm() / b.norm()
}

#[test]
fn the_schur_solve_is_the_dense_cholesky_solve() {
    let mut rng = Rng(0x5eed_a770);
    for (blocks, shared) in [(1, 1), (5, 3), (40, 4), (200, 2), (60, 0)] {
        let a = random_arrowhead(blocks, shared, &mut rng);
        let dense = a.to_dense();
        let n = a.n();
        assert_eq!(a.diagonal(), dense.diagonal());
        let x = DVector::from_fn(n, |_, _| rng.normal());
        assert!(rel_diff(&a.mul(&x), &(&dense * &x)) < 1e-13);
        let g = DVector::from_fn(n, |_, _| rng.normal());
        let d = DVector::from_fn(n, |_, _| 0.5 + rng.uniform());
        for lambda in [0.0, 1e-3, 10.0] {
            let mut damped = dense.clone();
            for j in 0..n {
                damped[(j, j)] += lambda * d[j];
            }
            let reference = damped.cholesky().expect("positive definite").solve(&g);
            let delta = a.damped_solve(&d, lambda, &g).expect("positive definite");
            let err = rel_diff(&delta, &reference);
            assert!(err < 1e-10, "{blocks} blocks, {shared} shared, λ {lambda}: relative difference {err:e}");
        }
    }
}

#[test]
fn inverse_and_sandwich_entries_are_the_dense_ones() {
    let mut rng = Rng(0xc0ff_ee00);
    let a = random_arrowhead(30, 3, &mut rng);
    let b = random_arrowhead(30, 3, &mut rng);
    // The same layout for B: rebuild it from B's entries on A's layout.
    let b = Arrowhead::from_dense(Arc::clone(a.layout()), &b.to_dense());
    let n = a.n();
    let (x, y) = (DVector::from_fn(n, |_, _| rng.normal()), DVector::from_fn(n, |_, _| rng.normal()));
    let ai = a.to_dense().cholesky().unwrap().inverse();
    let low = vec![(0.7, x.clone(), y.clone())];
    let reference = &ai * (b.to_dense() + 0.7 * &x * y.transpose()) * &ai;
    let inv = a.inverse_on_support().expect("positive definite");
    let sandwich = inv.sandwich(&b, &low);
    let scale = reference.amax();
    for g in 0..n {
        for h in 0..n {
            assert!((inv.entry(g, h) - ai[(g, h)]).abs() < 1e-10 * ai.amax(), "A⁻¹ ({g}, {h})");
            let s = sandwich.entry(g, h);
            assert!(
                (s - reference[(g, h)]).abs() < 1e-10 * scale,
                "sandwich ({g}, {h}): {s} vs {}",
                reference[(g, h)]
            );
        }
    }
    assert!(rel_diff(&inv.apply(&x), &(&ai * &x)) < 1e-10);
}

#[test]
fn a_singular_block_is_named_by_block_and_column() {
    let mut rng = Rng(7);
    let mut a = random_arrowhead(6, 2, &mut rng);
    // Block 4's own matrix made rank-deficient: its second column a copy of its first.
    let cols = a.layout().block(4).to_vec();
    assert!(cols.len() >= 2);
    let mut dense = a.to_dense();
    for &h in a.layout().block(4).iter().chain(a.layout().shared()) {
        dense[(cols[1], h)] = dense[(cols[0], h)];
        dense[(h, cols[1])] = dense[(h, cols[0])];
    }
    dense[(cols[1], cols[1])] = dense[(cols[0], cols[0])];
    dense[(cols[0], cols[1])] = dense[(cols[0], cols[0])];
    dense[(cols[1], cols[0])] = dense[(cols[0], cols[0])];
    a = Arrowhead::from_dense(Arc::clone(a.layout()), &dense);
    let n = a.n();
    let err =
        a.damped_solve(&DVector::from_element(n, 1.0), 0.0, &DVector::from_element(n, 1.0)).unwrap_err();
    assert_eq!(err, Singular { block: Some(4), column: cols[1] });
    assert_eq!(err.to_string(), format!("block 4 is not positive definite at column {}", cols[1]));
    assert_eq!(a.inverse_on_support().unwrap_err(), Singular { block: Some(4), column: cols[1] });
    // Damping makes it positive definite again.
    assert!(a.damped_solve(&DVector::from_element(n, 1.0), 1e-3, &DVector::from_element(n, 1.0)).is_ok());
    assert!(ArrowLayout::try_new(vec![Some(3)], 2).is_err());
}

const L_S: f64 = 4.5e-3;
const K_E: f64 = 0.539;
const N_P: u32 = 4;
const H: f64 = 1e-4;
/// Current noise σ [A].
const SIGMA: f64 = 0.05;

/// Log `i` of a fleet: its own winding temperature (R_s from 0.9 Ω up by the copper law
/// over 0..75 K), its own exciting input, noise of standard deviation σ on i_d, i_q: white
/// (`rho = 0`) or AR(1) with coefficient `rho`.
fn fleet_log(i: usize, n: usize, rho: f64) -> (Experiment, f64) {
    let r_s = 0.9 * (1.0 + 0.00393 * (i as f64 * 37.0 % 75.0));
    let model = PmsmSpm::new(N_P, VoltageHold::Stator);
    let mut rng = Rng(1000 + i as u64);
    let mut s = exciting_signals(n, H, 250.0, 60.0, K_E, &mut rng);
    let e = experiment(&format!("log{i}"), H, s.clone());
    let prep = Prepared::new(&model, &e).expect("prepare");
    let y = sim(&model, &prep, &[r_s, L_S, K_E]).expect("simulate");
    let mut noise = Rng(0xdead_beef ^ i as u64);
    let mut state = [0.0; 2];
    let mut next = |c: usize| {
        state[c] = rho * state[c] + (1.0 - rho * rho).sqrt() * SIGMA * noise.normal();
        state[c]
    };
    let (mut i_d, mut i_q) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..n {
        i_d.push(y[2 * k] + next(0));
        i_q.push(y[2 * k + 1] + next(1));
    }
    (s.i_d, s.i_q) = (i_d, i_q);
    (experiment(&format!("log{i}"), H, s), r_s)
}

fn joint_fit(logs: &[Experiment], structured_above: Option<usize>, solver: SolverKind) -> FitResult {
    let model = PmsmSpm::new(N_P, VoltageHold::Stator);
    let options =
        PemOptions { per_experiment: vec!["r_s".into()], structured_above, solver, ..Default::default() };
    let f = fit(&model, logs, &[1.0, 5e-3, 0.5], &options).expect("fit runs");
    assert!(f.solver.success, "{}", f.solver.termination);
    f
}

/// 30 logs, per-log R_s and initial states: 30 × 3 + 2 = 92 free parameters, past the
/// threshold (64) of the structured path. The dense path on the same problem gives the
/// same estimates and standard errors: with white noise (the white sandwich) and with
/// coloured noise (the batch means, one batch a log, their centring outside the blocks).
#[test]
fn a_mid_size_joint_fit_is_the_dense_one() {
    let cases = [
        (0.0, CovarianceMethod::White, SolverKind::Lm),
        (0.0, CovarianceMethod::White, SolverKind::Gn),
        (0.97, CovarianceMethod::BatchMeans, SolverKind::Lm),
    ];
    for (rho, method, solver) in cases {
        let (logs, _): (Vec<Experiment>, Vec<f64>) = (0..30).map(|i| fleet_log(i, 3000, rho)).unzip();
        let structured = joint_fit(&logs, None, solver);
        let dense = joint_fit(&logs, Some(usize::MAX), solver);
        assert_eq!(structured.uncertainty.method, method, "noise AR({rho})");
        assert_eq!(structured.solver.name, dense.solver.name);
        same_fit(&structured, &dense);
    }
}

fn same_fit(structured: &FitResult, dense: &FitResult) {
    assert_eq!(structured.parameters.len(), dense.parameters.len());
    let close = |a: f64, b: f64, tol: f64| (a - b).abs() <= tol * b.abs().max(f64::MIN_POSITIVE);
    for (s, d) in structured
        .parameters
        .iter()
        .zip(&dense.parameters)
        .chain(structured.initial_states.iter().zip(&dense.initial_states))
    {
        assert_eq!((&s.name, &s.experiment), (&d.name, &d.experiment));
        assert!(
            close(s.value, d.value, 1e-10),
            "{} {:?}: {:e} vs {:e}",
            s.name,
            s.experiment,
            s.value,
            d.value
        );
        for (a, b) in [(s.std_error, d.std_error), (s.std_error_white, d.std_error_white)] {
            assert!(close(a, b, 1e-8), "se of {} {:?}: {a:e} vs {b:e}", s.name, s.experiment);
        }
        assert!(close(s.error_index_percent, d.error_index_percent, 1e-8), "error index of {}", s.name);
    }
    assert_eq!(structured.uncertainty.method, dense.uncertainty.method);
    assert!(close(structured.fit.loss, dense.fit.loss, 1e-12));
}

/// 80 noisy logs (240 free parameters): the shared K_e and L_s and every per-log R_s
/// within their 95 % intervals, all but a few of the R_s (binomial: 80 × 5 %).
#[test]
fn a_fleet_recovers_shared_k_e_and_per_log_r_s() {
    let (logs, r_true): (Vec<Experiment>, Vec<f64>) = (0..80).map(|i| fleet_log(i, 4000, 0.0)).unzip();
    let f = joint_fit(&logs, None, SolverKind::Lm);
    for (name, truth) in [("k_e", K_E), ("l_s", L_S)] {
        let p = f.parameter(name).unwrap();
        eprintln!("{name}: {:.6e} ± {:.2e} (truth {truth:e})", p.value, p.std_error);
        assert!(p.experiment.is_none());
        assert!(p.ci95[0] <= truth && truth <= p.ci95[1], "{name} {:?} vs {truth}", p.ci95);
    }
    let r: Vec<_> = f.parameters.iter().filter(|p| p.name == "r_s").collect();
    assert_eq!(r.len(), 80);
    let outside = r.iter().zip(&r_true).filter(|(p, t)| !(p.ci95[0] <= **t && **t <= p.ci95[1])).count();
    eprintln!("{outside} of 80 R_s outside their 95 % interval");
    assert!(outside <= 10, "{outside} of 80 R_s outside their interval");
    assert_eq!(f.correlation_names, ["l_s", "k_e"], "the correlation is of the shared parameters");
    // The diagnostics take the shared parameters' error indices, not the per-log ones'.
    let flagged: Vec<_> = f.diagnostics.poorly_determined.iter().map(|p| &p.name).collect();
    assert!(flagged.is_empty(), "poorly determined: {flagged:?}");
}
