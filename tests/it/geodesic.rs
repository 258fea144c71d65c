//! The contract of `LeastSquares::directional_gradient` on the prediction-error problem:
//! `JᵀWε(q)` with the Jacobian at `p` equals the normal equations' `JᵀWε` at `q = p` (the
//! geodesic acceleration divides their difference by 0.005, so any mismatch of weights,
//! filters or parameters is magnified 200 times), for a dynamic model with its initial
//! state estimated, per-experiment parameters, sample and output weights and a residual
//! prefilter; and it moves with `q` as the residuals do.

use greybox::estimate::{Butterworth, LeastSquares, NominalScaling, PemProblem, ProblemOptions};
use greybox::model::Prepared;
use nalgebra::DVector;

#[test]
fn directional_gradient_at_the_point_is_the_normal_equations_gradient() {
    let (a, b, m, start) = crate::common::spm_records_off_truth();
    let h = a.h();
    let filter = Butterworth::try_new(4, 0.1 / h, h).unwrap();
    let cases = [
        (vec![(&a, None)], ProblemOptions { estimate_x0: true, ..Default::default() }),
        (
            vec![(&a, Some(0.5)), (&b, None)],
            ProblemOptions {
                per_experiment: vec!["r_s".into()],
                output_weights: Some(vec![1.0, 4.0]),
                estimate_x0: true,
                ..Default::default()
            },
        ),
        (
            vec![(&a, Some(2.0))],
            ProblemOptions {
                prefilters: vec![filter],
                output_weights: Some(vec![3.0, 0.5]),
                ..Default::default()
            },
        ),
    ];
    for (k, (logs, opts)) in cases.into_iter().enumerate() {
        let data =
            logs.iter().map(|(e, w)| (Prepared::new(&m, e).unwrap(), w.map(|w| vec![w; e.len()]))).collect();
        let problem = PemProblem::new(&m, data, &start, &NominalScaling, &opts).unwrap();
        let p = problem.start_vector(&start);
        let ne = LeastSquares::normal_equations(&problem, &p).unwrap();
        let at_p = LeastSquares::directional_gradient(&problem, &p, &p).unwrap().expect("quadratic loss");
        let scale = ne.jtr.amax();
        assert!(scale > 0.0, "case {k}: a zero gradient tests nothing");
        for (x, y) in at_p.iter().zip(ne.jtr.iter()) {
            assert!((x - y).abs() <= 1e-10 * scale, "case {k}: {x} vs {y} (largest {scale})");
        }
        // Away from p it is no longer the gradient: the residuals at q enter.
        let q = &p + DVector::from_element(p.len(), 0.01);
        let at_q = LeastSquares::directional_gradient(&problem, &p, &q).unwrap().unwrap();
        assert!((&at_q - &ne.jtr).amax() > 1e-6 * scale, "case {k}: q did not enter");
    }
}
