//! The streamed least squares (a tall-skinny QR folded block by block) against a dense QR
//! of the whole regressor matrix, the path it replaced: the same estimates to 1e-10 on a
//! fixed ill-scaled problem, on the logs and on the drive scenarios; the same bits on any
//! number of threads.

use greybox::drive::{DriveConfig, IPM_MOTOR, SPM_MOTOR, scenario, simulate_drive};
use greybox::estimate::{BLOCK, StreamedLeastSquares, solve_weighted};
use greybox::pmsm::{DqView, MotorKind, least_squares, regressors};
use nalgebra::{DMatrix, DVector};

/// Dense reference: Householder QR (nalgebra) of the row-weighted, column-equilibrated
/// regressors `phi` (rows × cols, row-major); θ, and E² from an explicit residual.
fn dense(phi: &[f64], y: &[f64], sqrt_w: &[f64], cols: usize) -> (Vec<f64>, f64) {
    let rows = y.len();
    let norms: Vec<f64> = (0..cols)
        .map(|j| (0..rows).map(|i| (sqrt_w[i] * phi[i * cols + j]).powi(2)).sum::<f64>().sqrt())
        .collect();
    let a = DMatrix::from_fn(rows, cols, |i, j| sqrt_w[i] * phi[i * cols + j] / norms[j]);
    let mut b = DVector::from_fn(rows, |i, _| sqrt_w[i] * y[i]);
    let qr = a.qr();
    qr.q_tr_mul(&mut b);
    let x = qr.r().solve_upper_triangular(&b.rows(0, cols).into_owned()).unwrap();
    let theta: Vec<f64> = (0..cols).map(|j| x[j] / norms[j]).collect();
    let e2 = (0..rows)
        .map(|i| {
            let fit: f64 = (0..cols).map(|j| phi[i * cols + j] * theta[j]).sum();
            (sqrt_w[i] * (y[i] - fit)).powi(2)
        })
        .sum();
    (theta, e2)
}

fn max_rel(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs() / y.abs()).fold(0.0, f64::max)
}

/// A fixed problem: 5 000 rows (not a multiple of the block), columns four decades apart and
/// correlated, noisy observations, uneven weights with zeros.
fn fixed_problem() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let theta = [1.3, -250.0, 0.02, 7.0];
    let (mut phi, mut y, mut w) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..5_000 {
        let t = i as f64 * 1e-3;
        let row =
            [1.0 + next(), 1e-3 * (t.sin() + 0.1 * next()), 1e2 * (t.cos() + next()), (3.0 * t).sin() + 0.5];
        let clean: f64 = row.iter().zip(&theta).map(|(a, b)| a * b).sum();
        phi.extend_from_slice(&row);
        y.push(clean + 1e-3 * next());
        w.push(if i % 97 == 0 { 0.0 } else { 1.0 + next() });
    }
    (phi, y, w)
}

#[test]
fn streamed_least_squares_matches_a_dense_qr() {
    let (phi, y, w) = fixed_problem();
    assert_ne!(y.len() % BLOCK, 0);
    let names: Vec<String> = (0..4).map(|j| format!("c{j}")).collect();
    let sol = solve_weighted(&names, &phi, &y, &w).unwrap();
    let (theta, e2) = dense(&phi, &y, &w, 4);
    let err = max_rel(&sol.theta, &theta);
    eprintln!("fixed problem: θ relative difference {err:.1e}, E² {:.1e}", (sol.e2 - e2).abs() / e2);
    assert!(err < 1e-10, "{err:e}");
    assert!((sol.e2 - e2).abs() < 1e-8 * e2);
    // The nested solution on the leading columns is the regression on those columns alone.
    let mut ls = StreamedLeastSquares::new(4);
    for ((row, yi), wi) in phi.chunks_exact(4).zip(&y).zip(&w) {
        ls.push(row, *yi, *wi);
    }
    let lead = ls.solve_leading(&names[..2]).unwrap();
    let two: Vec<f64> = phi.chunks_exact(4).flat_map(|r| [r[0], r[1]]).collect();
    let (theta2, e2_2) = dense(&two, &y, &w, 2);
    assert!(max_rel(&lead.theta, &theta2) < 1e-10);
    assert!((lead.e2 - e2_2).abs() < 1e-8 * e2_2);
    // A row of the wrong length is an error, not a panic.
    ls.push(&[1.0], 0.0, 1.0);
    assert!(ls.solve(&names).is_err());
}

/// The least-squares start on every log and both models, and on the drive scenarios.
#[test]
fn streamed_start_matches_a_dense_qr_on_logs_and_scenarios() {
    let mut logs = vec![(
        greybox::pmsm::read_log(
            concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"),
            &Default::default(),
        )
        .unwrap(),
        4,
    )];
    if crate::common::shared().is_some() {
        for (stem, n_p) in [
            ("servo_spm_moves_idinj", 4),
            ("servo_spm_moves_idinj_noisy", 4),
            ("servo_spm_pwm_deadtime_idinj", 4),
            ("ipm_moves_idinj", 2),
            ("gem_spm_moves_idinj", 4),
            ("gem_ipm_moves_idinj_noisy", 4),
        ] {
            logs.push((crate::common::load(stem).0, n_p));
        }
    }
    for (name, motor) in [("exp1", SPM_MOTOR), ("exp3", SPM_MOTOR), ("exp3", IPM_MOTOR), ("exp4", SPM_MOTOR)]
    {
        let cfg = DriveConfig { duration: 1.0, ..scenario(name, motor).unwrap() };
        logs.push((simulate_drive(&cfg).unwrap().experiment, motor.n_p));
    }
    for (e, n_p) in &logs {
        for kind in [MotorKind::Spm, MotorKind::Ipm] {
            let (phi, y) = regressors(&DqView::try_new(e).unwrap(), *n_p, kind).unwrap();
            let cols = kind.parameter_names().len();
            let (theta, _) = dense(&phi, &y, &vec![1.0; y.len()], cols);
            let Ok(ls) = least_squares(std::slice::from_ref(e), *n_p, kind) else {
                // A record that does not excite a column: the dense reference has no solution either.
                assert!(!theta.iter().all(|t| t.is_finite()), "{} {kind:?}: {theta:?}", e.name());
                continue;
            };
            let err = max_rel(&ls.theta, &theta);
            eprintln!("{} {kind:?}: θ relative difference {err:.1e}", e.name());
            assert!(err < 1e-10, "{} {kind:?}: {err:e}", e.name());
        }
    }
}

/// No thread pool is involved: one and two threads give the same bits.
#[test]
fn streamed_least_squares_is_bit_identical_on_any_thread_count() {
    let e = greybox::pmsm::read_log(
        concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz"),
        &Default::default(),
    )
    .unwrap();
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| least_squares(std::slice::from_ref(&e), 4, MotorKind::Spm).unwrap().theta)
    };
    let (one, two) = (on(1), on(2));
    assert!(one.iter().zip(&two).all(|(a, b)| a.to_bits() == b.to_bits()), "{one:?} {two:?}");
}
