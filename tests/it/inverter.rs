//! The inverter's voltage error as a nuisance input (MODEL.md §4): per phase
//! `−v_dt tanh(i_x/w)`, held in the stator frame, estimated beside the motor's parameters
//! from the reference voltage.

use crate::common::{Rng, Signals, exciting_signals, pmsm_options, rel, simulate_into};
use approx::{assert_relative_eq, relative_eq};
use greybox::Error;
use greybox::model::{GreyBoxModel, Prepared};
use greybox::pmsm::{
    DeadTimeMask, DqView, InverterModel, PmsmFitOptions, PmsmIpm, PmsmSpm, VoltageHold, VoltageInput,
    fit_pmsm,
};
use greybox::simulate::{SimOptions, visit_sensitivities};

const THETA: [f64; 4] = [0.9, 4.5e-3, 0.539, 6.0];
const N_P: u32 = 4;
const H: f64 = 1e-4;
const INVERTER: InverterModel = InverterModel { width: Some(1.0), known: None, mask: None };

fn model() -> PmsmSpm {
    PmsmSpm::new(N_P, VoltageHold::Stator).with_input(VoltageInput::REFERENCE).with_inverter(INVERTER)
}

/// Reference steps, the angle integrated from the speed, and currents simulated by `with`
/// (a model with the inverter error) at `theta`. The error depends on the currents it
/// drives, so the record is the fixed point of "simulate with the error of the last
/// currents", started from the currents of `plain` at `theta` without v_dt (converged to
/// 1e-13 A); `None` when it does not settle in 200 rounds.
fn record_with<P: GreyBoxModel, M: GreyBoxModel>(
    plain: &P,
    with: &M,
    theta: &[f64],
    seed: u64,
) -> Option<greybox::Experiment> {
    let mut rng = Rng(seed);
    let s = exciting_signals(8000, H, 250.0, 60.0, theta[theta.len() - 2], &mut rng);
    let mut angle = 0.0;
    let theta_m: Vec<f64> = s
        .w_m
        .iter()
        .map(|w| {
            let t = angle;
            angle += w * H;
            t
        })
        .collect();
    let refs =
        Signals { u_d_ref: Some(s.u_d.clone()), u_q_ref: Some(s.u_q.clone()), theta_m: Some(theta_m), ..s };
    let mut e = simulate_into(plain, &theta[..theta.len() - 1], H, refs);
    for _ in 0..200 {
        let next = simulate_into(with, theta, H, DqView::try_new(&e).unwrap().to_signals());
        let (a, b) = (DqView::try_new(&e).unwrap(), DqView::try_new(&next).unwrap());
        let change =
            a.i_d().iter().chain(a.i_q()).zip(b.i_d().iter().chain(b.i_q())).map(|(x, y)| (x - y).abs());
        let done = change.fold(0.0, f64::max) < 1e-13;
        e = next;
        if done {
            return Some(e);
        }
    }
    None
}

/// The SPM record of [`record_with`] at `THETA`.
fn record(seed: u64) -> greybox::Experiment {
    let plain = PmsmSpm::new(N_P, VoltageHold::Stator).with_input(VoltageInput::REFERENCE);
    record_with(&plain, &model(), &THETA, seed).expect("the record with the inverter error settles")
}

/// Salient machine with the inverter error: `(r_s, l_d, l_q, k_e, v_dt)`.
const THETA_IPM: [f64; 5] = [0.35, 3.2e-3, 7.5e-3, 0.4164, 6.0];

fn ipm() -> PmsmIpm {
    PmsmIpm::new(N_P, VoltageHold::Stator).with_input(VoltageInput::REFERENCE).with_inverter(INVERTER)
}

/// The interior-magnet model with the inverter error: the exact step is linear in the held
/// voltage, so ∂x⁺/∂v_dt is the homogeneous propagation driven by the error direction; it
/// matches central differences, and a noise-free fit recovers all five parameters.
#[test]
fn ipm_dead_time_is_recovered() {
    let plain = PmsmIpm::new(N_P, VoltageHold::Stator).with_input(VoltageInput::REFERENCE);
    // The first seed whose record settles (a seed's sign pattern can make the fixed point
    // cycle between two neighbours).
    let e = (1..20).find_map(|seed| record_with(&plain, &ipm(), &THETA_IPM, seed)).expect("a record settles");
    let m = ipm();
    let prep = Prepared::new(&m, &e).unwrap();
    let mut analytic = Vec::new();
    visit_sensitivities(&m, &prep, &THETA_IPM, &SimOptions::default(), |_, _, dy, _| {
        analytic.extend_from_slice(dy)
    })
    .unwrap();
    let sim = |th: &[f64]| greybox::simulate::simulate(&m, &prep, th, &SimOptions::default()).unwrap();
    for j in 0..5 {
        let d = 1e-6 * THETA_IPM[j];
        let (mut p, mut q) = (THETA_IPM, THETA_IPM);
        p[j] += d;
        q[j] -= d;
        let (yp, yq) = (sim(&p), sim(&q));
        let scale = (0..yp.len()).map(|r| analytic[r * 5 + j].abs()).fold(0.0, f64::max);
        let worst = (0..yp.len())
            .map(|r| ((yp[r] - yq[r]) / (2.0 * d) - analytic[r * 5 + j]).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-5 * scale, "parameter {j}: {worst:e} of {scale:e}");
    }
    let options = PmsmFitOptions {
        model: greybox::pmsm::MotorKind::Ipm,
        input: VoltageInput::REFERENCE,
        inverter: Some(INVERTER),
        ..pmsm_options(N_P)
    };
    let fit = fit_pmsm(&[e], &options).unwrap();
    for (j, name) in ["r_s", "l_d", "l_q", "k_e", "v_dt"].iter().enumerate() {
        let v = fit.parameter(name).unwrap().value;
        assert!(relative_eq!(v, THETA_IPM[j], max_relative = 1e-6), "{name}: {v:e} vs {:e}", THETA_IPM[j]);
    }
}

/// The analytic sensitivity to v_dt (and to the others) matches central differences.
#[test]
fn dead_time_sensitivities_match_central_differences() {
    let e = record(1);
    let m = model();
    let prep = Prepared::new(&m, &e).unwrap();
    let mut analytic = Vec::new();
    visit_sensitivities(&m, &prep, &THETA, &SimOptions::default(), |_, _, dy, _| {
        analytic.extend_from_slice(dy)
    })
    .unwrap();
    let sim = |th: &[f64]| greybox::simulate::simulate(&m, &prep, th, &SimOptions::default()).unwrap();
    for j in 0..4 {
        let d = 1e-6 * THETA[j];
        let (mut p, mut q) = (THETA, THETA);
        p[j] += d;
        q[j] -= d;
        let (yp, yq) = (sim(&p), sim(&q));
        let scale = (0..yp.len()).map(|r| analytic[r * 4 + j].abs()).fold(0.0, f64::max);
        let worst = (0..yp.len())
            .map(|r| ((yp[r] - yq[r]) / (2.0 * d) - analytic[r * 4 + j]).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-5 * scale, "parameter {j}: {worst:e} of {scale:e}");
    }
}

/// Noise-free, the motor's parameters and v_dt come back from the reference voltage; the
/// report flags v_dt as a nuisance parameter.
#[test]
fn dead_time_voltage_is_recovered() {
    let options =
        PmsmFitOptions { input: VoltageInput::REFERENCE, inverter: Some(INVERTER), ..pmsm_options(N_P) };
    let fit = fit_pmsm(&[record(2)], &options).unwrap();
    for (j, name) in ["r_s", "l_s", "k_e", "v_dt"].iter().enumerate() {
        let p = fit.parameter(name).unwrap();
        assert!(
            relative_eq!(p.value, THETA[j], max_relative = 1e-6),
            "{name}: {:e} vs {:e}",
            p.value,
            THETA[j]
        );
        assert_eq!(p.nuisance, *name == "v_dt");
    }
    assert!(fit.to_json().contains("\"nuisance\": true"));
    // A known v_dt is held fixed.
    let known = PmsmFitOptions { inverter: Some(InverterModel { known: Some(6.0), ..INVERTER }), ..options };
    let fit = fit_pmsm(&[record(2)], &known).unwrap();
    let v = fit.parameter("v_dt").unwrap();
    assert!(v.fixed && v.value == 6.0);
}

#[test]
fn dead_time_errors_name_the_culprit() {
    // No angle: the phase currents are unknown.
    let mut s = DqView::try_new(&record(2)).unwrap().to_signals();
    s.theta_m = None;
    let e = s.into_experiment("no angle", H).unwrap();
    match model().prepare(&e).unwrap_err() {
        Error::MissingChannel { channel, .. } => assert_eq!(channel, "theta_m"),
        other => panic!("{other}"),
    }
    // Currents that never reverse in a phase: v_dt is not identifiable.
    let mut s = DqView::try_new(&record(2)).unwrap().to_signals();
    s.i_d = vec![5.0; s.i_d.len()];
    s.i_q = vec![0.0; s.i_q.len()];
    s.theta_m = Some(vec![0.0; s.i_d.len()]);
    let e = s.into_experiment("one direction", H).unwrap();
    let err = model().prepare(&e).unwrap_err();
    assert!(err.to_string().contains("never crosses zero"), "{err}");
}

/// The PWM log with 3 µs dead time and 0.8 V device drop, fitted from its reference voltage:
/// the inverter model takes most of the error out of R_s and finds v_dt near
/// t_d f_sw U_dc + V_on; with the dead-time mask it meets the inverter issue's targets.
/// Measured: output error without the model r_s 4.41 Ω, with it 1.41 Ω (truth 0.9), v_dt
/// 7.98 V (expected 9.2 V); with the mask (0.813 A, one-step prediction): r_s −0.09 %,
/// l_s +0.26 %, k_e −0.05 %, v_dt 9.2016 V.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn pwm_log_from_the_reference_voltage() {
    crate::common::require_shared!();
    let (e, t) = crate::common::load("servo_spm_pwm_deadtime_idinj");
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(crate::common::data("servo_spm_pwm_deadtime_idinj.json")).unwrap(),
    )
    .unwrap();
    let f = |k: &str| json[k].as_f64().unwrap();
    let expected =
        f("dead_time_s") * f("switching_frequency_Hz") * f("u_dc_V") + f("device_threshold_voltage_V");
    let options = PmsmFitOptions { input: VoltageInput::REFERENCE, ..pmsm_options(t.n_p) };
    let naive = fit_pmsm(std::slice::from_ref(&e), &options).unwrap();
    let with =
        fit_pmsm(&[e], &PmsmFitOptions { inverter: Some(InverterModel::default()), ..options.clone() })
            .unwrap();
    let r = |f: &greybox::pmsm::PmsmFit| f.parameter("r_s").unwrap().value;
    let v_dt = with.parameter("v_dt").unwrap().value;
    eprintln!(
        "PWM log from the reference: r_s {:.4} Ω without the inverter model, {:.4} Ω with it (truth {}); v_dt {v_dt:.3} V \
         (t_d f_sw U_dc + V_on = {expected:.3} V)",
        r(&naive),
        r(&with),
        t.r_s
    );
    assert!((r(&with) - t.r_s).abs() < 0.25 * (r(&naive) - t.r_s).abs());
    assert!((v_dt - expected).abs() < 0.2 * expected, "v_dt {v_dt}");
    // The dead-time mask (threshold 4 h v_dt / L from the fit): the targets, r_s and
    // l_s within 1 %, k_e within 0.1 %, v_dt within 1 % of t_d f_sw U_dc + V_on.
    let (e, _) = crate::common::load("servo_spm_pwm_deadtime_idinj");
    let inverter = Some(InverterModel { mask: Some(DeadTimeMask::Auto), ..Default::default() });
    let best_options = PmsmFitOptions { inverter, ..options.clone() };
    let best = fit_pmsm(&[e], &best_options).unwrap();
    let v_dt = best.parameter("v_dt").unwrap().value;
    let value = |n: &str| best.parameter(n).unwrap().value;
    let err = |n: &str, truth: f64| rel(value(n), truth);
    eprintln!(
        "PWM log, dead-time mask: r_s {:.2e}, l_s {:.2e}, k_e {:.2e} relative error, v_dt {v_dt:.4} V ({:?})",
        err("r_s", t.r_s),
        err("l_s", t.l_d),
        err("k_e", t.k_e),
        best.pmsm_notes.last()
    );
    assert!(relative_eq!(v_dt, expected, max_relative = 0.01), "v_dt {v_dt}");
    assert_relative_eq!(value("r_s"), t.r_s, max_relative = 0.01);
    assert_relative_eq!(value("l_s"), t.l_d, max_relative = 0.01);
    assert_relative_eq!(value("k_e"), t.k_e, max_relative = 1e-3);
    assert!(
        best.inverter.is_some_and(|i| matches!(i.mask, Some(DeadTimeMask::Current(c)) if c > 0.5 && c < 1.5))
    );
    // The sign width found by search is the one the voltage equation prefers (≈ 0.45 A,
    // the current ripple), and v_dt stays within 1 %.
    let (e, _) = crate::common::load("servo_spm_pwm_deadtime_idinj");
    let input = VoltageInput::Reference { delay: 1, advance: 1.5, speed_pll: Some(1600.0) };
    let pem = greybox::estimate::PemOptions { horizon: Some(1), ..Default::default() };
    let options =
        PmsmFitOptions { inverter: Some(InverterModel::default()), input, pem, ..pmsm_options(t.n_p) };
    let search = greybox::pmsm::InputSearch { dead_time_width: true, ..Default::default() };
    let found = greybox::pmsm::fit_estimating_input(&[e], &options, search).unwrap();
    let note = found.pmsm_notes.iter().find(|n| n.contains("sign width")).unwrap();
    let w: f64 = note.split_whitespace().find_map(|x| x.parse().ok()).unwrap();
    eprintln!("PWM log: {note}; v_dt {:.3} V", found.parameter("v_dt").unwrap().value);
    assert!((0.3..0.6).contains(&w), "{note}");
    assert_relative_eq!(found.parameter("v_dt").unwrap().value, expected, max_relative = 0.01);
}

/// A saved fit with the reference input, the inverter model and a cable validates as the
/// fit had it: reading the report back keeps all three, and the noise-free record is
/// reproduced (before, validation silently simulated the terminal voltage without cable or
/// inverter).
#[test]
fn saved_fit_with_reference_inverter_and_cable_validates() {
    let e = record(2);
    let options = PmsmFitOptions {
        input: VoltageInput::REFERENCE,
        inverter: Some(INVERTER),
        cable_resistance: 0.2,
        ..pmsm_options(N_P)
    };
    let fit = fit_pmsm(std::slice::from_ref(&e), &options).unwrap();
    let saved = greybox::pmsm::SavedModel::from_json(&fit.to_json(), None, None).unwrap();
    assert_eq!(
        (saved.input, saved.inverter, saved.cable_resistance),
        (VoltageInput::REFERENCE, Some(INVERTER), 0.2)
    );
    assert_eq!(saved.theta.len(), 4);
    let c = &saved.validate(&[e]).unwrap()[0];
    assert!(c.metrics.fit_percent.iter().all(|f| *f > 99.999), "{:?}", c.metrics.fit_percent);
}

/// The dead-time mask's errors: a threshold that leaves too few samples names the log and
/// asks for a lower one; a negative threshold is refused.
#[test]
fn dead_time_mask_errors_name_the_culprit() {
    let e = record(2);
    let fit = |t: f64| {
        let inverter = Some(InverterModel { mask: Some(DeadTimeMask::Current(t)), ..INVERTER });
        fit_pmsm(
            std::slice::from_ref(&e),
            &PmsmFitOptions { inverter, input: VoltageInput::REFERENCE, ..pmsm_options(N_P) },
        )
    };
    let err = fit(30.0).unwrap_err();
    assert!(err.to_string().contains("clear of zero"), "{err}");
    let err = fit(-1.0).unwrap_err();
    assert!(err.to_string().contains("non-negative"), "{err}");
    // A modest threshold keeps most of the record and still fits.
    assert!(fit(0.05).unwrap().solver.success);
}

/// The models' dead-time directions, computed a window of intervals at a time, are those of
/// the per-sample formula (library `sin_cos` and `tanh`) to the bit, for records that end
/// just before, on and after a window's edge, with angles past the inline reduction's limit.
#[test]
fn windowed_directions_are_the_per_sample_formula_to_the_bit() {
    use greybox::data::Channel;
    use greybox::pmsm::dead_time_directions;
    use greybox::pmsm::{clarke, inverse_clarke};
    for n in [255usize, 256, 257, 258, 511, 512, 513, 514, 3000] {
        let th: Vec<f64> = (0..n).map(|k| 0.0131 * k as f64 + if k % 97 == 5 { 3e5 } else { 0.0 }).collect();
        let id: Vec<f64> = (0..n).map(|k| 2.0 * (0.021 * k as f64).sin() - 0.3).collect();
        let iq: Vec<f64> = (0..n).map(|k| 10.0 * (0.007 * k as f64).cos()).collect();
        let zeros = vec![0.0; n];
        let channel = |name: &str, unit: &str, v: &[f64]| Channel::new(name, unit, v.to_vec());
        let e = greybox::Experiment::try_new(
            "windows",
            1e-4,
            vec![
                channel("ud", "V", &zeros),
                channel("uq", "V", &zeros),
                channel("id", "A", &id),
                channel("iq", "A", &iq),
                channel("w_m", "rad/s", &zeros),
                channel("theta_m", "rad", &th),
            ],
        )
        .unwrap();
        let width = 0.3;
        let model = InverterModel { width: Some(width), ..Default::default() };
        let new = dead_time_directions(&DqView::try_new(&e).unwrap(), N_P, &model).unwrap();
        let sign = |x: f64| if x.abs() >= 19.5 { x.signum() } else { x.tanh() };
        let sample = |k: usize| {
            let (s, c) = (f64::from(N_P) * th[k]).sin_cos();
            let (a, b, cc) = inverse_clarke(c * id[k] - s * iq[k], s * id[k] + c * iq[k]);
            ([a, b, cc], (s, c))
        };
        assert_eq!(new.len(), n - 1);
        for (k, d) in new.iter().enumerate() {
            let ((p, (s, c)), (q, _)) = (sample(k), sample(k + 1));
            let sg = |x: f64, y: f64| -sign((0.5 * (x + y)) / width);
            let (alpha, beta) = clarke(sg(p[0], q[0]), sg(p[1], q[1]), sg(p[2], q[2]));
            let (re, im) = (c * alpha + s * beta, -s * alpha + c * beta);
            assert!(d.re.to_bits() == re.to_bits() && d.im.to_bits() == im.to_bits(), "n = {n}, k = {k}");
        }
    }
}
