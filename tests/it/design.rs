//! `greybox design` (issue 32): the predicted standard errors of exp3 and exp6 against the
//! issue's numbers (4 s, 0.05 A current noise), and the plans' D-ranking.

use greybox::drive::design::predict_plan;
use greybox::drive::{SPM_MOTOR, scenario};
use greybox::estimate::design::Criterion;

fn plan(name: &str) -> greybox::drive::design::PlanPrediction {
    let mut cfg = scenario(name, SPM_MOTOR).unwrap();
    cfg.duration = 4.0;
    cfg.sensors.current_noise = 0.05;
    predict_plan(&cfg).unwrap()
}

#[test]
fn design_predicts_issue_numbers_and_ranks_plans() {
    let (e3, e6) = (plan("exp3"), plan("exp6"));
    let r3 = e3.prediction.parameter("r_s").unwrap().std_error;
    let r6 = e6.prediction.parameter("r_s").unwrap().std_error;
    assert!((r3 / 1.8e-4 - 1.0).abs() < 0.05, "exp3 se(R_s) {r3}");
    assert!((r6 / 1.45e-4 - 1.0).abs() < 0.1, "exp6 se(R_s) {r6}");
    assert!((e3.prediction.condition_number / 96.0 - 1.0).abs() < 0.05);
    let order = Criterion::D.rank(&[e3.prediction.clone(), e6.prediction.clone()]);
    assert_eq!(order, vec![1, 0]);
}

#[test]
fn design_rejects_zero_noise() {
    let cfg = scenario("exp3", SPM_MOTOR).unwrap();
    assert!(predict_plan(&cfg).is_err());
}
