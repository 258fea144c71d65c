//! Saturation (issue 33, deliverables 1 and 2): the saturated step against the exact
//! linear step and a fine integration; the drive simulator's saturated plant; the linear
//! IPM fit's load-dependent bias and the saturated fit's recovery; flux maps (synthetic,
//! with a Monte Carlo of the intervals, and the measured one).

use crate::common::{Rng, TempFile, data, require_shared};
use greybox::data::{Channel, Experiment};
use greybox::drive::{IPM_MOTOR, IPM_SATURATION, Profile, SATURATED_IPM_MOTOR, scenario, simulate_drive};
use greybox::pmsm::{
    C64, ExactPlant, FluxMapOptions, MapModel, PmsmFitOptions, Saturation, SaturationExponents, VoltageHold,
    fit_flux_map, fit_pmsm, fit_saturated, read_flux_map, saturated_step, saturated_substeps,
};

#[test]
fn linear_magnetics_step_equals_the_exact_ipm_step() {
    // With every saturation coefficient zero the RK4 step must reproduce the exact
    // (matrix-exponential) IPM step with the stator hold, to the RK4 tolerance.
    let m = IPM_MOTOR;
    let sat = Saturation::linear(m.l_d, m.l_q, m.psi_f);
    let h = 1e-4;
    let mut plant = ExactPlant::new(m.n_p, h, true, VoltageHold::Stator).unwrap();
    for (i, u0, w_m) in
        [([1.0, 5.0], C64::new(10.0, 60.0), 150.0), ([-4.0, -8.0], C64::new(-30.0, 20.0), -280.0)]
    {
        let exact = plant.step(&m, i, u0, w_m).unwrap();
        let w_e = f64::from(m.n_p) * w_m;
        let n = saturated_substeps(&sat, m.r_s, 10.0, w_e, h).unwrap();
        let rk4 = saturated_step(&sat, m.r_s, i, u0, w_e, h, n).unwrap();
        for a in 0..2 {
            assert!((rk4[a] - exact[a]).abs() < 1e-8 * (1.0 + exact[a].abs()), "{rk4:?} vs {exact:?}");
        }
    }
}

#[test]
fn saturated_step_meets_its_tolerance_against_a_fine_integration() {
    let sat = IPM_SATURATION;
    let (h, r_s) = (1e-4, 0.4);
    for (i, u0, w_e) in
        [([0.0, 9.0], C64::new(-20.0, 120.0), 800.0), ([-6.0, -7.0], C64::new(40.0, -90.0), -500.0_f64)]
    {
        let n = saturated_substeps(&sat, r_s, 12.0, w_e.abs(), h).unwrap();
        let coarse = saturated_step(&sat, r_s, i, u0, w_e, h, n).unwrap();
        let fine = saturated_step(&sat, r_s, i, u0, w_e, h, 64 * n).unwrap();
        // The substep rule (ρ ≤ 0.025 per substep) keeps a period's error within 1e-8.
        for a in 0..2 {
            assert!((coarse[a] - fine[a]).abs() < 1e-8 * (1.0 + fine[a].abs()), "{coarse:?} vs {fine:?}");
        }
    }
}

#[test]
fn linear_saturation_in_the_simulator_reproduces_the_linear_plant() {
    let mut cfg = scenario("exp3", IPM_MOTOR).unwrap();
    cfg.duration = 0.5;
    let linear = simulate_drive(&cfg).unwrap();
    cfg.saturation = Some(Saturation::linear(IPM_MOTOR.l_d, IPM_MOTOR.l_q, IPM_MOTOR.psi_f));
    let saturated = simulate_drive(&cfg).unwrap();
    for c in ["id", "iq", "w_m"] {
        let (a, b) = (linear.experiment.channel(c).unwrap(), saturated.experiment.channel(c).unwrap());
        let worst = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-7, "{c}: {worst}");
    }
    // A ψ_f ramp has no meaning for the saturated plant: refused, naming the field.
    cfg.psi_f_factor = Profile(vec![(0.0, 1.0), (0.2, 0.9)]);
    let e = simulate_drive(&cfg).unwrap_err().to_string();
    assert!(e.contains("saturation") && e.contains("psi_f_factor"), "{e}");
}

/// The saturating IPM on exp3 (1.5 s) under a constant load torque \[N m\].
fn saturated_log(load: f64, noise: f64, seed: u64) -> Experiment {
    let mut cfg = scenario("exp3", SATURATED_IPM_MOTOR).unwrap();
    cfg.saturation = Some(IPM_SATURATION);
    cfg.duration = 1.5;
    cfg.mechanics.load = Profile(vec![(0.0, load)]);
    cfg.sensors.current_noise = noise;
    cfg.seed = seed;
    simulate_drive(&cfg).unwrap().experiment
}

fn truth_theta() -> [f64; 7] {
    let t = IPM_SATURATION.theta();
    [SATURATED_IPM_MOTOR.r_s, t[0], t[1], t[2], t[3], t[4], t[5]]
}

#[test]
fn the_motor_saturates_as_claimed() {
    // L_q falls ≥ 30 % from no load to rated current (i_max = 10 A), apparent and incremental.
    let no_load = IPM_SATURATION.inductances([0.0, 1e-3]).unwrap();
    let rated = IPM_SATURATION.inductances([0.0, 10.0]).unwrap();
    let drop = |a: f64, b: f64| 1.0 - b / a;
    assert!(drop(no_load.l_q_apparent.unwrap(), rated.l_q_apparent.unwrap()) >= 0.30);
    assert!(drop(no_load.l_qq, rated.l_qq) >= 0.30);
}

#[test]
fn linear_fit_drifts_with_load_and_the_saturated_fit_recovers_the_truth() {
    let options = PmsmFitOptions::new(SATURATED_IPM_MOTOR.n_p);
    let theta = truth_theta();
    let k_e = SATURATED_IPM_MOTOR.k_e();
    let mut l_q = Vec::new();
    let mut k_e_bias = Vec::new();
    for load in [0.0, 4.0] {
        // Noise-free: the saturated fit to the RK4 tolerance, the linear one biased.
        let fit = fit_saturated(&[saturated_log(load, 0.0, 1)], &options, IPM_SATURATION.exponents).unwrap();
        assert!(fit.fit.solver.success);
        for (p, t) in fit.fit.parameters.iter().zip(theta) {
            assert!((p.value / t - 1.0).abs() < 2e-6, "load {load}: {} = {} (truth {t})", p.name, p.value);
        }
        let lin = |n: &str| fit.linear.parameter(n).unwrap().value;
        l_q.push(lin("l_q"));
        k_e_bias.push(lin("k_e") / k_e - 1.0);
        assert!((fit.fit.derived("k_e").unwrap().value / k_e - 1.0).abs() < 1e-7);
        // Noisy: every coefficient within 4 standard errors (the coverage itself is the
        // example `saturation`'s Monte Carlo), the linear residual larger.
        let fit = fit_saturated(&[saturated_log(load, 0.1, 7)], &options, IPM_SATURATION.exponents).unwrap();
        for (p, t) in fit.fit.parameters.iter().zip(theta) {
            assert!(
                (p.value - t).abs() < 4.0 * p.std_error,
                "load {load}: {} = {} ± {} (truth {t})",
                p.name,
                p.value,
                p.std_error
            );
        }
    }
    // The linear L_q falls with the load (the apparent inductance of a saturating axis);
    // its K_e is off by more than 1e-4 at every load where the saturated fit's is within
    // 1e-7 (the sign and size of the linear bias depend on the record: the example
    // `saturation` reports them per load).
    assert!(l_q[1] < 0.85 * l_q[0], "{l_q:?}");
    assert!(k_e_bias.iter().all(|b| b.abs() > 1e-4), "{k_e_bias:?}");
}

/// A flux map of `m` on the current grid i_d ∈ −20…20, i_q ∈ −26…26 (step 2 A), with
/// Gaussian flux noise σ \[V s\].
pub(crate) fn synthetic_map(m: &Saturation, sigma: f64, rng: &mut Rng) -> Experiment {
    let mut cols = vec![Vec::new(); 4];
    for a in 0..21 {
        for b in 0..27 {
            let i = [-20.0 + 2.0 * f64::from(a), -26.0 + 2.0 * f64::from(b)];
            let psi = m.flux(i).unwrap();
            cols[0].push(i[0]);
            cols[1].push(i[1]);
            cols[2].push(psi[0] + sigma * rng.normal());
            cols[3].push(psi[1] + sigma * rng.normal());
        }
    }
    let names = ["i_d", "i_q", "psi_d", "psi_q"];
    let units = ["A", "A", "V s", "V s"];
    let channels = names.iter().zip(units).zip(cols).map(|((n, u), v)| Channel::new(*n, u, v)).collect();
    Experiment::try_new("synthetic", 1.0, channels).unwrap()
}

/// A saturating machine in the flux map's range: the Baldor-like PM-assisted SyRM's order
/// of magnitude (L_d0 ≈ 25 mH, L_q0 ≈ 140 mH, ψ_f = 0.45 V s).
pub(crate) const MAP_MOTOR: Saturation = Saturation {
    a_d0: 40.0,
    a_dd: 30.0,
    a_q0: 7.0,
    a_qq: 4.0,
    a_dq: 50.0,
    psi_f: 0.45,
    exponents: SaturationExponents { s: 2, t: 4, u: 1, v: 1 },
};

#[test]
fn a_noise_free_map_is_recovered_and_its_exponents_found() {
    let map = synthetic_map(&MAP_MOTOR, 0.0, &mut Rng(1));
    let fit = fit_flux_map(&map, &FluxMapOptions::default()).unwrap();
    assert_eq!(fit.exponents, MAP_MOTOR.exponents);
    for (p, t) in fit.fit.parameters.iter().zip(MAP_MOTOR.theta()) {
        assert!((p.value / t - 1.0).abs() < 1e-7, "{} = {} (truth {t})", p.name, p.value);
    }
    assert!(fit.rms_residual < 1e-9 * fit.range);
}

#[test]
fn flux_map_intervals_cover_the_truth() {
    // 200 noisy maps (σ = 2 mV s): each coefficient's 95 % interval covers the truth in
    // 95 % ± 3.5 % of them (the binomial band at ±2.3 standard deviations for n = 200).
    let mut rng = Rng(42);
    let options = FluxMapOptions { exponents: Some(MAP_MOTOR.exponents), skip_check: true };
    let mut covered = [0usize; 6];
    let n = 200;
    for _ in 0..n {
        let map = synthetic_map(&MAP_MOTOR, 2e-3, &mut rng);
        let fit = fit_flux_map(&map, &options).unwrap();
        for (j, (p, t)) in fit.fit.parameters.iter().zip(MAP_MOTOR.theta()).enumerate() {
            covered[j] += usize::from(p.ci95[0] <= t && t <= p.ci95[1]);
        }
    }
    for (j, c) in covered.iter().enumerate() {
        let rate = *c as f64 / f64::from(n);
        assert!((0.915..=0.985).contains(&rate), "coefficient {j}: coverage {rate} ({covered:?})");
    }
}

#[test]
fn a_csv_flux_map_reads_like_the_experiment_and_bad_maps_are_named() {
    let map = synthetic_map(&MAP_MOTOR, 0.0, &mut Rng(1));
    let file = TempFile::new("fluxmap", "map.csv");
    let mut text = String::from("i_d,i_q,psi_d,psi_q\n");
    let c = |n: &str| map.channel(n).unwrap().to_vec();
    let (a, b, d, q) = (c("i_d"), c("i_q"), c("psi_d"), c("psi_q"));
    for k in 0..map.len() {
        text += &format!("{:e},{:e},{:e},{:e}\n", a[k], b[k], d[k], q[k]);
    }
    std::fs::write(file.path(), text).unwrap();
    let read = read_flux_map(file.path()).unwrap();
    assert_eq!(read.len(), map.len());
    assert_eq!(read.channel("psi_q").unwrap(), &q[..]);
    std::fs::write(file.path(), "i_d,i_q,psi_d\n1,2,3\n").unwrap();
    let e = read_flux_map(file.path()).unwrap_err().to_string();
    assert!(e.contains("psi_q"), "{e}");
    let npz = TempFile::new("fluxmap", "map.npz");
    std::fs::write(npz.path(), b"not a zip").unwrap();
    let e = read_flux_map(npz.path()).unwrap_err().to_string();
    assert!(e.contains("npz") && e.contains("zip"), "{e}");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn the_measured_flux_map_is_fitted() {
    require_shared!();
    let map = read_flux_map(data("real/baldor_400rpm_map.npz")).unwrap();
    assert_eq!(map.len(), 21 * 27);
    let fit = fit_flux_map(&map, &FluxMapOptions::default()).unwrap();
    // The rms flux residual is under 1 % of the map's range (2.6 V s), every free
    // coefficient has a finite standard error, and ψ_f lies near the map's no-load flux.
    assert!(fit.rms_residual < 0.01 * fit.range, "{} of {}", fit.rms_residual, fit.range);
    assert!(fit.fit.parameters.iter().all(|p| p.at_bound || p.std_error.is_finite()));
    let psi_f = fit.model.psi_f;
    assert!((psi_f - 0.444).abs() < 0.1, "ψ_f {psi_f}");
    // Saturation: the q-axis apparent inductance falls by more than half over the map.
    let l = |p: usize| fit.operating_points[p].l_q_apparent.unwrap();
    assert!(l(2) < 0.5 * 1.0 / fit.model.a_q0 && l(1) > l(2));
}

/// A map the saturation model describes (noise-free, its own family): the check keeps the
/// model (its 5-fold held-out error is the lower), the no-load flux is its ψ_f, and the
/// inductances agree with the map's differences: trusted.
#[test]
fn a_map_of_the_model_family_keeps_the_model() {
    let map = synthetic_map(&MAP_MOTOR, 0.0, &mut Rng(1));
    let fit = fit_flux_map(&map, &FluxMapOptions::default()).unwrap();
    let check = fit.check.as_ref().unwrap();
    assert_eq!(check.chosen, MapModel::Saturation, "held out {:?}", check.held_out_rms);
    assert!((check.no_load.0 / MAP_MOTOR.psi_f - 1.0).abs() < 1e-6, "{:?}", check.no_load);
    assert!(check.warnings.is_empty(), "{:?}", check.warnings);
}

/// The measured Baldor map: the saturation model's flux at zero current is 12 % above the
/// map's 0.444 V s; the splines predict the map's held-out points 16 times better and are
/// chosen; the reported no-load flux lies within 1 % of the map's and its interval covers
/// it; the incremental inductances at the printed points lie within 10 % of the map's
/// central differences; trusted.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn the_measured_flux_map_keeps_its_no_load_flux() {
    require_shared!();
    let map = read_flux_map(data("real/baldor_400rpm_map.npz")).unwrap();
    let fit = fit_flux_map(&map, &FluxMapOptions::default()).unwrap();
    let c = fit.check.as_ref().unwrap();
    eprintln!("{c}");
    assert!((fit.model.psi_f / 0.4441 - 1.0) > 0.1, "the saturation model's ψ_f {}", fit.model.psi_f);
    assert_eq!(c.chosen, MapModel::Spline);
    let m = c.no_load_map.unwrap();
    assert!((c.no_load.0 / m - 1.0).abs() < 0.01 && (c.no_load.0 - m).abs() <= 1.96 * c.no_load.1);
    for p in &c.points {
        let (own, map) = (p.model_stencil.unwrap(), p.map.unwrap());
        assert!((own[0] / map[0] - 1.0).abs() < 0.1 && (own[1] / map[1] - 1.0).abs() < 0.1, "{p:?}");
    }
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
}

#[test]
fn the_linear_fit_is_the_start_and_stays_available() {
    // The saturated workflow refuses a log its linear IPM fit cannot start from.
    let mut cfg = scenario("exp3", SATURATED_IPM_MOTOR).unwrap();
    cfg.saturation = Some(IPM_SATURATION);
    cfg.duration = 0.3;
    let log = simulate_drive(&cfg).unwrap().experiment;
    let linear = fit_pmsm(std::slice::from_ref(&log), &PmsmFitOptions::new(3)).unwrap();
    assert!(linear.parameter("r_s").is_some());
    let e = fit_saturated(&[log], &PmsmFitOptions::new(0), IPM_SATURATION.exponents).unwrap_err();
    assert!(e.to_string().contains("pole"), "{e}");
}

/// A linear machine's log (motulator's `ipm_moves_idinj`, linear magnetics): the default
/// start ends in a local minimum far above the linear fit (a_dd ≈ 6.5e3, residual 1000×
/// the linear one); the second start, from the linear model the saturated one contains,
/// finds the machine, and the verdict says why it is not trusted: a coefficient at its
/// bound zero, not a local minimum.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn a_linear_log_gives_the_linear_machine_back() {
    require_shared!();
    let options = greybox::pmsm::CsvOptions { pole_pairs: Some(2), ..Default::default() };
    let log = greybox::pmsm::read_log(data("ipm_moves_idinj.csv.gz"), &options).unwrap();
    let fit = fit_saturated(&[log], &PmsmFitOptions::new(2), SaturationExponents::default()).unwrap();
    let reasons = fit.untrusted_reasons();
    assert!(!reasons.iter().any(|r| r == "local_minimum"), "{reasons:?}\n{fit}");
    assert!(!fit.trusted() && reasons.iter().any(|r| r == "parameter_at_bound"), "{reasons:?}\n{fit}");
    let derived = |name: &str| fit.fit.derived(name).unwrap().value;
    for (value, truth) in [(derived("l_d0"), 3.2e-3), (derived("l_q0"), 7.5e-3), (fit.model.psi_f, 0.17)] {
        assert!((value / truth - 1.0).abs() < 1e-4, "{value} vs {truth}\n{fit}");
    }
    for name in ["a_dd", "a_qq", "a_dq"] {
        let p = fit.fit.parameter(name).unwrap();
        assert!(p.at_bound || (p.ci95[0] <= 0.0 && 0.0 <= p.ci95[1]), "{name}: {p:?}\n{fit}");
    }
}
