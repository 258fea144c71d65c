//! The statistics at a point after a normal-equation pass there (whose Grams the problem
//! keeps and the statistics take: quadratic loss, unit weights) against those of a problem
//! that ran no pass: the same sums to 1e-12 and the same lag sums of the raw residuals to the bit, for one
//! experiment with its initial state estimated and for two with a per-experiment `r_s`;
//! likewise after a pass flagged as the solver's last, which gathered the lag sums itself.

use greybox::drive::SPM_MOTOR;
use greybox::estimate::Sums;
use greybox::estimate::{LeastSquares, NominalScaling, PemProblem, ProblemOptions};
use greybox::model::Prepared;
use greybox::pmsm::{PmsmSpm, VoltageHold};

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

fn assert_same(kept: &Sums, full: &Sums) {
    assert!(close(kept.cost, full.cost), "cost {} vs {}", kept.cost, full.cost);
    assert!(close(kept.e2_weighted, full.e2_weighted));
    assert_eq!(kept.count, full.count);
    for (a, b) in kept.sse.iter().zip(&full.sse).chain(kept.sst.iter().zip(&full.sst)) {
        assert!(close(*a, *b), "{a} vs {b}");
    }
    for (a, b) in [(&kept.jtj, &full.jtj), (&kept.bread, &full.bread), (&kept.meat, &full.meat)] {
        let (a, b) = (a.to_dense(), b.to_dense());
        assert_eq!(a.shape(), b.shape());
        let scale = b.amax();
        for (x, y) in a.iter().zip(b.iter()) {
            assert!((x - y).abs() <= 1e-12 * scale, "{x} vs {y} (largest entry {scale})");
        }
    }
    // The whiteness test's lag sums, to the bit.
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(kept.lag_sums.len(), full.lag_sums.len());
    for (k, f) in kept.lag_sums.iter().flatten().zip(full.lag_sums.iter().flatten()) {
        assert_eq!(k.n(), f.n());
        assert_eq!(k.total().to_bits(), f.total().to_bits());
        for (a, b) in [(k.dots(), f.dots()), (k.head(), f.head()), (k.tail(), f.tail())] {
            assert_eq!(bits(a), bits(b));
        }
    }
}

#[test]
fn statistics_after_the_normal_equations_equal_a_full_pass() {
    let (a, b, m, start) = crate::common::spm_records_off_truth();
    let cases = [
        (vec![&a], ProblemOptions { estimate_x0: true, ..Default::default() }),
        (vec![&a, &b], ProblemOptions { per_experiment: vec!["r_s".into()], ..Default::default() }),
    ];
    for (logs, opts) in cases {
        let build = || {
            let data = logs.iter().map(|e| (Prepared::new(&m, e).unwrap(), None)).collect();
            PemProblem::new(&m, data, &start, &NominalScaling, &opts).unwrap()
        };
        let (kept, gathered, fresh) = (build(), build(), build());
        let p = kept.start_vector(&start);
        let ne = kept.normal_equations(&p).unwrap();
        let full = fresh.sums(&p).unwrap();
        assert_same(&kept.sums(&p).unwrap(), &full);
        // A pass flagged as the solver's last also keeps the residuals' lag sums: the same
        // normal equations to the bit, and the statistics without another pass.
        let ne_last = LeastSquares::normal_equations_likely_last(&gathered, &p).unwrap();
        assert_eq!(ne_last.cost.to_bits(), ne.cost.to_bits());
        assert!(
            ne_last
                .jtj
                .to_dense()
                .iter()
                .zip(ne.jtj.to_dense().iter())
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        assert!(ne_last.jtr.iter().zip(ne.jtr.iter()).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert!(gathered.statistics_kept(&p) && !kept.statistics_kept(&p) && !fresh.statistics_kept(&p));
        assert_same(&gathered.sums(&p).unwrap(), &full);
    }
}

/// A fit started by its prediction (its start's pass handed to the solver) against a fit
/// from nothing, both holds: the same estimate, loss, errors and iterations to the bit, and
/// its predicted loss that of [`greybox::estimate::predicted_loss`].
#[test]
fn a_fit_continued_from_its_prediction_equals_a_fresh_fit() {
    use greybox::estimate::{PemOptions, StartedFit, Uniform, fit_with_weighting, predicted_loss};
    let (e, _, _, start) = crate::common::spm_records_off_truth();
    let opts = PemOptions::default();
    for hold in [VoltageHold::Stator, VoltageHold::Dq] {
        let m = PmsmSpm::new(SPM_MOTOR.n_p, hold);
        let fresh = fit_with_weighting(&m, std::slice::from_ref(&e), &start, &opts, &Uniform).unwrap();
        let started = StartedFit::new(&m, std::slice::from_ref(&e), &start, &opts, &Uniform).unwrap();
        let predicted = started.predicted_loss();
        let cont = started.fit().unwrap();
        assert_eq!(cont.fit.loss.to_bits(), fresh.fit.loss.to_bits(), "{hold}");
        assert_eq!(cont.solver.iterations, fresh.solver.iterations);
        assert_eq!(cont.solver.evaluations, fresh.solver.evaluations);
        for (a, b) in cont.parameters.iter().zip(&fresh.parameters) {
            assert_eq!(a.value.to_bits(), b.value.to_bits(), "{hold} {}", a.name);
            assert_eq!(a.std_error.to_bits(), b.std_error.to_bits(), "{hold} {}", a.name);
        }
        let alone = predicted_loss(&m, std::slice::from_ref(&e), &start, &opts, &Uniform).unwrap();
        assert_eq!(predicted.to_bits(), alone.to_bits(), "{hold}");
        assert!(
            cont.solver.iterations > 0 && predicted.is_finite() && predicted >= 0.0,
            "{hold}: {predicted}"
        );
    }
}
