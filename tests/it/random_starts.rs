//! Basin of attraction of the global minimum: from random starts with every parameter
//! drawn log-uniformly in [0.2×, 5×] of the truth, Levenberg-Marquardt must reach the
//! estimate of the fit from the least-squares start (to 1e-6 relative) in ≥ 99 % of the
//! starts. The truth is used only to centre the random starts, which is the point here.

use crate::common::{Rng, exciting_signals, experiment, load, pmsm_options, simulate_into};
use approx::relative_eq;
use greybox::Experiment;
use greybox::pmsm::{DqView, HoldChoice, PmsmFitOptions, PmsmSpm, VoltageHold, fit_pmsm};

const NAMES: [&str; 3] = ["r_s", "l_s", "k_e"];
/// Starts lie in `[truth / SPAN, truth × SPAN]`, log-uniform.
const SPAN: f64 = 5.0;

fn estimate(fit: &greybox::estimate::FitResult) -> Vec<f64> {
    NAMES.iter().map(|n| fit.parameter(n).expect("estimated").value).collect()
}

fn show(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| format!("{x:.6e}")).collect::<Vec<_>>().join(", "))
}

/// Fits `log` from `starts` random starts around `truth`; returns the fraction [%] that
/// reach the least-squares-start estimate, printing every start that does not.
fn success_rate(label: &str, log: &Experiment, n_p: u32, truth: [f64; 3], starts: usize, seed: u64) -> f64 {
    success_rate_with(label, log, HoldChoice::Stator, n_p, truth, starts, seed)
}

fn success_rate_with(
    label: &str,
    log: &Experiment,
    hold: HoldChoice,
    n_p: u32,
    truth: [f64; 3],
    starts: usize,
    seed: u64,
) -> f64 {
    let opts = PmsmFitOptions { hold, ..pmsm_options(n_p) };
    let reference = fit_pmsm(std::slice::from_ref(log), &opts).expect("fit from the LS start");
    assert!(reference.solver.success, "{label}: LS-start fit: {}", reference.solver.termination);
    let best = estimate(&reference);
    eprintln!("{label}: LS-start fit {}, loss {:.6e}", show(&best), reference.fit.loss);
    let mut rng = Rng(seed);
    let (mut reached, mut iterations) = (0usize, 0u64);
    for i in 0..starts {
        let start: Vec<f64> =
            truth.iter().map(|t| t * (SPAN.ln() * (2.0 * rng.uniform() - 1.0)).exp()).collect();
        let o = PmsmFitOptions { start: Some(start.clone()), ..opts.clone() };
        match fit_pmsm(std::slice::from_ref(log), &o) {
            Ok(fit) => {
                iterations += fit.solver.iterations;
                let end = estimate(&fit);
                if end.iter().zip(&best).all(|(a, b)| relative_eq!(*a, *b, max_relative = 1e-6)) {
                    reached += 1;
                } else {
                    eprintln!(
                        "{label}: start {i} {} ended at {}: {} after {} iterations, loss {:.6e}",
                        show(&start),
                        show(&end),
                        fit.solver.termination,
                        fit.solver.iterations,
                        fit.fit.loss
                    );
                }
            }
            Err(e) => eprintln!("{label}: start {i} {}: error {e}", show(&start)),
        }
    }
    let rate = 100.0 * reached as f64 / starts as f64;
    eprintln!(
        "{label}: {reached} of {starts} starts reach the global minimum ({rate:.1} %), mean {:.1} iterations",
        iterations as f64 / starts as f64
    );
    rate
}

/// A simulated SPM record (stator hold, 3000 samples, speed to 250 rad/s) with light
/// current noise (σ 0.05 A).
#[test]
fn simulated_record_from_400_random_starts() {
    let truth = [0.9, 4.5e-3, 0.539];
    let mut rng = Rng(77);
    let signals = exciting_signals(3000, 1e-4, 250.0, 60.0, truth[2], &mut rng);
    let clean = simulate_into(&PmsmSpm::new(4, VoltageHold::Stator), &truth, 1e-4, signals);
    let mut s = DqView::try_new(&clean).expect("PMSM channels").to_signals();
    let mut noise = Rng(99);
    for v in s.i_d.iter_mut().chain(s.i_q.iter_mut()) {
        *v += 0.05 * noise.normal();
    }
    let log = experiment("simulated", 1e-4, s);
    let rate = success_rate("simulated", &log, 4, truth, 400, 12345);
    assert!(rate >= 99.0, "simulated record: only {rate:.1} % of the random starts reach the minimum");
}

/// The first 2.5 s of the servo log: ±30 rad/s, +100 rad/s and the whole −4 A
/// d-current injection (0.9–1.7 s).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn servo_log_from_200_random_starts() {
    crate::common::require_shared!();
    let (log, t) = load("servo_spm_moves_idinj");
    let log = log.slice(0..25_000).expect("2.5 s of the log");
    let rate = success_rate("servo 0–2.5 s", &log, t.n_p, [t.r_s, t.l_d, t.k_e], 200, 54321);
    assert!(rate >= 99.0, "servo log: only {rate:.1} % of the random starts reach the minimum");
}

/// The trust issue's case: 1 s of the servo log with the automatic hold, where 21 of 200
/// starts used to stall in the stator-hold fit with L_s at its lower bound and the dq-hold
/// fit (loss 65 times the minimum) was then reported as a success. A stalled hold fit is
/// now restarted from the other hold's estimate: ≥ 99.5 % of the starts reach the minimum.
/// `GREYBOX_STARTS` sets the number of starts (default 200; the note reports 1000).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn servo_log_automatic_hold_from_random_starts() {
    crate::common::require_shared!();
    let (log, t) = load("servo_spm_moves_idinj");
    let log = log.slice(0..10_000).expect("1 s of the log");
    let starts = std::env::var("GREYBOX_STARTS").ok().and_then(|s| s.parse().ok()).unwrap_or(200);
    let rate = success_rate_with(
        "servo 0–1 s, auto hold",
        &log,
        HoldChoice::Auto,
        t.n_p,
        [t.r_s, t.l_d, t.k_e],
        starts,
        2024,
    );
    assert!(rate >= 99.5, "only {rate:.1} % of the random starts reach the minimum");
}

/// A trial step that takes a parameter bounded above zero past zero puts it at a hundredth
/// of its value (the fraction-to-the-boundary rule of `LeastSquares::project_trial`): such a
/// step on `l_s` tries it at 1 % of its value, where plain projection put it at its default
/// lower bound 1e-12 H (a far start's trials there each cost a pass of 27 matrix squarings
/// a sample in the interior-magnet model); a step that stays positive, however small, and
/// the initial states (bounded on both sides of zero) are projected as before.
#[test]
fn a_trial_past_zero_puts_a_positive_parameter_at_a_hundredth_of_its_value() {
    use greybox::estimate::{LeastSquares, NominalScaling, PemProblem, ProblemOptions};
    use greybox::model::Prepared;
    let truth = [0.9, 4.5e-3, 0.539];
    let mut rng = Rng(7);
    let signals = exciting_signals(500, 1e-4, 250.0, 60.0, truth[2], &mut rng);
    let m = PmsmSpm::new(4, VoltageHold::Stator);
    let e = simulate_into(&m, &truth, 1e-4, signals);
    let opts = ProblemOptions { estimate_x0: true, ..Default::default() };
    let pb =
        PemProblem::new(&m, vec![(Prepared::new(&m, &e).unwrap(), None)], &truth, &NominalScaling, &opts)
            .unwrap();
    let p = pb.start_vector(&truth);
    assert_eq!(p.len(), 5, "r_s, l_s, k_e and the two initial currents");
    let mut step = p.clone();
    step[0] = -0.5 * p[0]; // past zero
    step[1] = 0.0; // to zero: past the bound
    step[2] = 1e-9 * p[2]; // positive: projected as before
    step[3] = -p[3] - 1.0; // an initial state: its own bounds only
    let (mut trial, mut plain) = (step.clone(), step.clone());
    LeastSquares::project_trial(&pb, &p, &mut trial);
    pb.project(&mut plain);
    assert_eq!(trial[0], 0.01 * p[0]);
    assert_eq!(trial[1], 0.01 * p[1]);
    assert_eq!(trial[2], step[2]);
    assert_eq!(plain[2], step[2]);
    assert_eq!(trial[3], plain[3]);
    assert_eq!(trial[4], step[4]);
    let theta = pb.theta(0, &plain);
    assert!(theta[0] <= 1e-11 && theta[1] <= 1e-11, "plain projection: r_s, l_s {theta:?} at their bound");
}
