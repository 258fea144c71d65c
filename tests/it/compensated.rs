//! Bias-compensated least squares (`estimate::correction`): a one-step predictor restarted
//! from a noisy measured state is biased (errors in the variables); subtracting the noise's
//! share of the criterion removes the bias.

use crate::errors::Scalar;
use greybox::data::Channel;
use greybox::estimate::{CriterionCorrection, PemOptions, Weighting, fit_with_weighting};
use greybox::model::Parameter;
use greybox::{Experiment, Result};

/// The noise `σ²` on the restart of each of `n` one-step predictions enters the criterion
/// as `½ (n − 1) a² σ²`.
#[derive(Debug)]
struct RestartNoise {
    n: usize,
    sigma2: f64,
}
impl CriterionCorrection for RestartNoise {
    fn term(&self, _: usize, theta: &[f64]) -> Result<(f64, Vec<f64>)> {
        let m = (self.n - 1) as f64 * self.sigma2;
        Ok((0.5 * m * theta[0] * theta[0], vec![m * theta[0]]))
    }
}

/// Uniform weights, and the compensation when given.
#[derive(Debug)]
struct Compensating(Option<RestartNoise>);
impl Weighting for Compensating {
    fn name(&self) -> String {
        "uniform".into()
    }
    fn is_uniform(&self) -> bool {
        self.0.is_none()
    }
    fn sample_weight(&self, _: &Experiment, _: usize) -> f64 {
        1.0
    }
    fn criterion_correction(&self) -> Option<&dyn CriterionCorrection> {
        self.0.as_ref().map(|c| c as &dyn CriterionCorrection)
    }
}

/// A log of `n` samples of `a = 0.9` driven by ±1 steps, its output with white noise of
/// standard deviation `sigma` (a linear congruential generator and Box–Muller, seeded).
fn noisy_log(n: usize, sigma: f64, seed: u64) -> Experiment {
    let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    let mut uniform = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let u: Vec<f64> = (0..n).map(|k| if (k / 7 + k / 13) % 2 == 0 { 1.0 } else { -1.0 }).collect();
    let mut x = vec![0.0; n];
    for k in 1..n {
        x[k] = 0.9 * x[k - 1] + u[k - 1];
    }
    let y = x
        .iter()
        .map(|v| v + sigma * (-2.0 * uniform().ln()).sqrt() * (2.0 * std::f64::consts::PI * uniform()).cos())
        .collect();
    Experiment::try_new("first_order", 1.0, vec![Channel::new("u", "-", u), Channel::new("y", "-", y)])
        .unwrap()
}

/// 20 logs with noise of 0.5 on a state of standard deviation 1.9: the plain one-step fit
/// is biased (attenuation, `a σ_x²/(σ_x² + σ²)`, about −0.06 here), many standard errors
/// of the mean; the compensated one is not, and each of its estimates lies within 3 of its
/// standard errors of the truth.
#[test]
fn the_compensated_one_step_fit_is_unbiased_where_the_plain_one_is_not() {
    let model = Scalar { p: vec![Parameter::free("a", "-", 0.5)] };
    let options = PemOptions { horizon: Some(1), estimate_x0: false, ..Default::default() };
    let (n, sigma) = (4000, 0.5);
    let mut errors = [Vec::new(), Vec::new()];
    for seed in 1..=20 {
        let e = noisy_log(n, sigma, seed);
        for (j, weighting) in
            [Compensating(None), Compensating(Some(RestartNoise { n, sigma2: sigma * sigma }))]
                .iter()
                .enumerate()
        {
            let fit =
                fit_with_weighting(&model, std::slice::from_ref(&e), &[0.5], &options, weighting).unwrap();
            let a = fit.parameter("a").unwrap();
            assert!(fit.solver.success, "{}", fit.solver.termination);
            if j == 1 {
                let z = (a.value - 0.9) / a.std_error;
                assert!(z.abs() < 3.0, "seed {seed}: a = {} ± {}, z {z:.2}", a.value, a.std_error);
            }
            errors[j].push(a.value - 0.9);
        }
    }
    let mean_and_sem = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
        (m, (var / v.len() as f64).sqrt())
    };
    let (plain, plain_sem) = mean_and_sem(&errors[0]);
    let (compensated, sem) = mean_and_sem(&errors[1]);
    eprintln!("mean error: plain {plain:.4} ± {plain_sem:.4}, compensated {compensated:.4} ± {sem:.4}");
    assert!(plain < -10.0 * plain_sem, "the plain fit's bias is what the test is about");
    assert!(compensated.abs() < 3.0 * sem, "compensated: {compensated} ± {sem}");
}
