//! Joint fits of several logs of one motor (MODEL.md §3): two records at winding
//! temperatures T0 and T0 + 60 K share L_s and K_e, while R_s follows the copper law
//! `R(T) = R0 (1 + α (T − T0))`, α = 0.00393 1/K. One R_s per log (`per_experiment`) must
//! give back both resistances and the temperature difference; one R_s for both must not fit.

use crate::common::{Rng, exciting_signals, experiment, pmsm_options, rel, sim};
use approx::relative_eq;
use greybox::estimate::{FitResult, PemOptions};
use greybox::model::Prepared;
use greybox::pmsm::PmsmError;
use greybox::pmsm::{HoldChoice, PmsmFitOptions, PmsmSpm, VoltageHold, fit_pmsm};
use greybox::{Error, Experiment};

const R0: f64 = 0.9;
const L_S: f64 = 4.5e-3;
const K_E: f64 = 0.539;
const N_P: u32 = 4;
const H: f64 = 1e-4;
const N: usize = 4000;
/// Copper temperature coefficient [1/K] (MODEL.md §3).
const ALPHA: f64 = 0.00393;
/// Winding temperature above T0 of the second log [K].
const DT_HOT: f64 = 60.0;
/// Current noise σ [A] of the noisy variant.
const SIGMA: f64 = 0.1;

fn r_at(dt: f64) -> f64 {
    R0 * (1.0 + ALPHA * dt)
}

/// A stator-held SPM record named `name` with resistance `r_s`, simulated from rest with
/// its own random exciting input; white noise σ [A] on i_d, i_q when `sigma > 0`.
fn record(name: &str, r_s: f64, input_seed: u64, sigma: f64) -> Experiment {
    let model = PmsmSpm::new(N_P, VoltageHold::Stator);
    let theta = [r_s, L_S, K_E];
    let mut rng = Rng(input_seed);
    let mut s = exciting_signals(N, H, 250.0, 60.0, K_E, &mut rng);
    let e = experiment(name, H, s.clone());
    let prep = Prepared::new(&model, &e).expect("prepare");
    let y = sim(&model, &prep, &theta).expect("simulate");
    let mut noise = Rng(input_seed ^ 0xdead_beef_cafe_f00d);
    s.i_d = (0..N).map(|k| y[2 * k] + sigma * noise.normal()).collect();
    s.i_q = (0..N).map(|k| y[2 * k + 1] + sigma * noise.normal()).collect();
    experiment(name, H, s)
}

fn logs(sigma: f64) -> [Experiment; 2] {
    [record("cold", r_at(0.0), 11, sigma), record("hot", r_at(DT_HOT), 23, sigma)]
}

fn joint(logs: &[Experiment], per_experiment: &[&str]) -> FitResult {
    let opts = PmsmFitOptions {
        hold: HoldChoice::Stator,
        pem: PemOptions {
            per_experiment: per_experiment.iter().map(|s| s.to_string()).collect(),
            ..Default::default()
        },
        ..pmsm_options(N_P)
    };
    let fit = fit_pmsm(logs, &opts).expect("fit runs");
    eprintln!("{fit}");
    assert!(fit.solver.success, "{}", fit.solver.termination);
    fit.report
}

/// The `r_s` estimate of experiment `name`.
fn r_of<'a>(fit: &'a FitResult, name: &str) -> &'a greybox::estimate::ParameterEstimate {
    fit.parameters
        .iter()
        .find(|p| p.name == "r_s" && p.experiment.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no r_s of `{name}` in {:?}", fit.parameters))
}

#[test]
fn per_log_resistance_recovers_the_temperature_difference() {
    let fit = joint(&logs(0.0), &["r_s"]);
    assert_eq!(fit.experiments, ["cold", "hot"]);
    assert_eq!(fit.parameters.iter().filter(|p| p.name == "r_s").count(), 2);
    for p in fit.parameters.iter().filter(|p| p.name != "r_s") {
        assert_eq!(p.experiment, None, "{} is shared", p.name);
    }
    let (r1, r2) = (r_of(&fit, "cold").value, r_of(&fit, "hot").value);
    for (name, est, truth) in [
        ("r_s[cold]", r1, r_at(0.0)),
        ("r_s[hot]", r2, r_at(DT_HOT)),
        ("l_s", fit.parameter("l_s").unwrap().value, L_S),
        ("k_e", fit.parameter("k_e").unwrap().value, K_E),
    ] {
        eprintln!("{name}: {est:.9e}, relative error {:.2e}", rel(est, truth));
        assert!(relative_eq!(est, truth, max_relative = 1e-6), "{name}: {est:e} vs {truth:e}");
    }
    let dt = (r2 / r1 - 1.0) / ALPHA;
    eprintln!("ΔT = {dt:.6} K (truth {DT_HOT} K)");
    assert!((dt - DT_HOT).abs() < 0.1, "ΔT = {dt} K");
}

#[test]
fn noisy_per_log_resistances_within_three_standard_errors() {
    let fit = joint(&logs(SIGMA), &["r_s"]);
    for (name, truth) in [("cold", r_at(0.0)), ("hot", r_at(DT_HOT))] {
        let p = r_of(&fit, name);
        let z = (p.value - truth) / p.std_error;
        eprintln!("r_s[{name}]: {:.6} ± {:.2e} Ω, {z:+.2} standard errors", p.value, p.std_error);
        assert!(z.abs() < 3.0, "r_s[{name}] = {} ± {} vs {truth}", p.value, p.std_error);
    }
    for (name, truth) in [("l_s", L_S), ("k_e", K_E)] {
        let p = fit.parameter(name).unwrap();
        let z = (p.value - truth) / p.std_error;
        eprintln!("{name}: {:.6e} ± {:.2e}, {z:+.2} standard errors", p.value, p.std_error);
        assert!(z.abs() < 3.0, "{name} = {} ± {} vs {truth}", p.value, p.std_error);
    }
    let (r1, r2) = (r_of(&fit, "cold"), r_of(&fit, "hot"));
    let dt = (r2.value / r1.value - 1.0) / ALPHA;
    // First-order propagation, ignoring the (small) correlation of the two R_s.
    let se_dt = (r2.value / r1.value) / ALPHA
        * ((r1.std_error / r1.value).powi(2) + (r2.std_error / r2.value).powi(2)).sqrt();
    eprintln!("ΔT = {dt:.3} ± {se_dt:.3} K");
    assert!((dt - DT_HOT).abs() < 3.0 * se_dt, "ΔT = {dt} ± {se_dt} K");
}

/// A 60 K difference is 24 % of R_s: one shared R_s leaves a systematic error that
/// dwarfs the noise, while the per-log fit is left with the noise alone.
#[test]
fn shared_resistance_fits_clearly_worse() {
    let logs = logs(SIGMA);
    let per_log = joint(&logs, &["r_s"]);
    let shared = joint(&logs, &[]);
    let r = shared.parameter("r_s").unwrap().value;
    let noise_loss = 0.5 * (2 * 2 * (N - 1)) as f64 * SIGMA * SIGMA;
    eprintln!(
        "loss: per-log R_s {:.4e}, shared R_s {:.4e} (white noise alone ≈ {noise_loss:.4e}); shared r_s {r:.4}",
        per_log.fit.loss, shared.fit.loss
    );
    assert!(shared.parameter("r_s").unwrap().experiment.is_none());
    assert!(r_at(0.0) < r && r < r_at(DT_HOT), "shared r_s {r} between the two");
    assert!(rel(per_log.fit.loss, noise_loss) < 0.05, "per-log loss is the noise's");
    assert!(shared.fit.loss > 10.0 * per_log.fit.loss);
    // Likelihood ratio: one parameter fewer may raise the loss by ≈ σ²/2 by chance, not more.
    let lr = (shared.fit.loss - per_log.fit.loss) / (SIGMA * SIGMA);
    assert!(lr > 100.0, "loss increase {lr} σ²");
}

#[test]
fn unknown_per_experiment_name_is_an_error() {
    let opts = PmsmFitOptions {
        hold: HoldChoice::Stator,
        pem: PemOptions { per_experiment: vec!["r_x".into()], ..Default::default() },
        ..pmsm_options(N_P)
    };
    let err = fit_pmsm(&logs(0.0), &opts).unwrap_err();
    assert!(matches!(err, Error::InvalidOption { .. }), "{err}");
    assert!(err.to_string().contains("r_x"), "{err}");
}

/// The pole-pair number is one property of the motor, given once for all the logs of a
/// joint fit (`PmsmFitOptions::pole_pairs`; logs no longer carry one): a joint fit without
/// it is refused, naming n_p.
#[test]
fn joint_fit_without_pole_pairs_is_refused() {
    let [a, b] = logs(0.0);
    let opts = PmsmFitOptions { hold: HoldChoice::Stator, ..pmsm_options(0) };
    let err = fit_pmsm(&[a, b], &opts).unwrap_err();
    assert!(matches!(err.domain(), Some(PmsmError::InvalidPolePairs { n_p: 0 })), "{err:?}");
    assert!(err.to_string().contains("n_p"), "{err}");
}
