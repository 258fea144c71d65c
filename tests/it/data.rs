//! Data-input layer: CSV reading of the development logs, unit options, Clarke/Park,
//! dq from phase quantities, and a clear error for every kind of bad input.

use crate::common::TempFile;
use greybox::pmsm::PmsmError;
use std::f64::consts::{PI, SQRT_2};
use std::path::Path;
use std::sync::LazyLock;

use crate::common::{Signals, read as read_csv, shared_file};
use approx::assert_relative_eq;
use greybox::Error;
use greybox::data::{Channel, Experiment};
use greybox::data::{ColumnMap, CsvSpec};
use greybox::pmsm::{
    AngleUnit, CsvOptions, DqSource, DqView, Frame, MIN_SAMPLES, Scale, SpeedUnit, read_logs,
};
use greybox::pmsm::{
    clarke, currents_to_dq, inverse_clarke, inverse_park, park, stator_held_voltages_to_dq,
    stator_hold_mean_factor,
};
use proptest::prelude::*;

// Development logs (../shared/data, or $GREYBOX_SHARED_DATA; see `common::shared_dir`).
static SERVO: LazyLock<String> = LazyLock::new(|| shared_file("servo_spm_moves_idinj.csv.gz"));
static GEM: LazyLock<String> = LazyLock::new(|| shared_file("gem_spm_moves_idinj.csv.gz"));
static GEM_NOISY: LazyLock<String> = LazyLock::new(|| shared_file("gem_ipm_moves_idinj_noisy.csv.gz"));
const SAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/sample.csv.gz");

/// A fresh file path under the system temp dir, unique per process and call.
fn temp_path(tag: &str, ext: &str) -> TempFile {
    TempFile::new("test", &format!("{tag}.{ext}"))
}

/// Writes `contents` to a fresh temp file and returns its path.
fn temp_file(tag: &str, contents: &[u8]) -> TempFile {
    let p = temp_path(tag, "csv");
    std::fs::write(&p, contents).expect("write temp file");
    p
}

/// A valid 6-column log of `n` rows at h = 1 ms (t, ud, uq, id, iq, w_m).
fn valid_rows(n: usize) -> String {
    let mut s = String::from("t,ud,uq,id,iq,w_m\n");
    for k in 0..n {
        let t = k as f64 * 1e-3;
        s.push_str(&format!("{t:.6},{},{},{},{},{}\n", 0.1 * k as f64, 1.0, 0.5, -0.25, 10.0));
    }
    s
}

fn read_default(p: &Path) -> greybox::Result<Experiment> {
    read_csv(p, 4, &CsvOptions::default())
}

// ---------------------------------------------------------------- real logs

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn reads_motulator_log() {
    crate::common::require_shared!();
    let e = read_csv(&*SERVO, 4, &CsvOptions::default()).unwrap();
    assert_eq!(e.name(), "servo_spm_moves_idinj");
    assert_eq!(e.len(), 72_000);
    // The experiment no longer carries n_p (the model does): check its channels instead.
    let names: Vec<&str> = e.channels().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["ud", "uq", "id", "iq", "w_m", "theta_m", "ud_ref", "uq_ref"]);
    assert!((e.h() - 1e-4).abs() < 1e-12, "h = {}", e.h());
    let v = DqView::try_new(&e).unwrap();
    let s = v.to_signals();
    assert_eq!(s.theta_m.as_ref().map(Vec::len), Some(72_000));
    assert_eq!(s.u_d_ref.as_ref().map(Vec::len), Some(72_000));
    assert_eq!(s.u_q_ref.as_ref().map(Vec::len), Some(72_000));
    // Row 1 of the file: 0.000100,0,0,-5.363765e-10,0.0001616121,-0.03324986,-1.663893e-06,...
    assert_eq!(v.i_d()[1], -5.363765e-10);
    assert_eq!(v.i_q()[1], 0.0001616121);
    assert_eq!(v.w_m()[1], -0.03324986);
    assert_eq!(v.theta_m().unwrap()[1], -1.663893e-06);
    assert_eq!(s.u_q_ref.as_ref().unwrap()[1], -0.001827789);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn reads_gem_log_without_references() {
    crate::common::require_shared!();
    let e = read_csv(&*GEM, 4, &CsvOptions::default()).unwrap();
    assert_eq!(e.name(), "gem_spm_moves_idinj");
    assert_eq!(e.len(), 58_400);
    assert!((e.h() - 1.25e-4).abs() < 1e-12, "h = {}", e.h());
    let v = DqView::try_new(&e).unwrap();
    assert!(v.theta_m().is_some());
    assert!(v.to_signals().u_d_ref.is_none());
    assert!(v.to_signals().u_q_ref.is_none());
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn reads_many_in_order() {
    crate::common::require_shared!();
    let v = read_logs(&[&*GEM, &*SERVO], &CsvOptions::default()).unwrap();
    assert_eq!(v.len(), 2);
    assert_eq!(v[0].name(), "gem_spm_moves_idinj");
    assert_eq!(v[1].name(), "servo_spm_moves_idinj");
    let missing = temp_path("many-missing", "csv");
    let err = read_logs(&[Path::new(&*GEM), &missing], &CsvOptions::default()).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err:?}");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn sample_log_is_a_verbatim_cut_of_the_servo_log() {
    crate::common::require_shared!();
    let sample = read_csv(SAMPLE, 4, &CsvOptions::default()).unwrap();
    let full = read_csv(&*SERVO, 4, &CsvOptions::default()).unwrap();
    assert_eq!(sample.name(), "sample");
    assert_eq!(sample.len(), 20_000);
    assert!((sample.h() - 1e-4).abs() < 1e-12);
    // t = 0.6 s is row 6000 of the full log.
    let cut = full.slice(6_000..26_000).unwrap();
    assert_eq!(DqView::try_new(&sample).unwrap().to_signals(), DqView::try_new(&cut).unwrap().to_signals());
}

/// Half a unit in the 7th significant digit of `x`: the rounding of a `%.7g` field.
fn q7(x: f64) -> f64 {
    if x == 0.0 { 0.0 } else { 0.5 * 10f64.powf(x.abs().log10().floor() - 6.0) }
}

/// The named columns of a gzip CSV, parsed independently of greybox's reader.
fn raw_columns(path: &str, names: &[&str]) -> Vec<Vec<f64>> {
    let gz = flate2::read::MultiGzDecoder::new(std::fs::File::open(path).unwrap());
    let mut rdr = csv::Reader::from_reader(gz);
    let header = rdr.headers().unwrap().clone();
    let idx: Vec<usize> = names.iter().map(|n| header.iter().position(|h| h == *n).unwrap()).collect();
    let mut cols = vec![Vec::new(); names.len()];
    for rec in rdr.records() {
        let rec = rec.unwrap();
        for (c, &i) in cols.iter_mut().zip(&idx) {
            c.push(rec[i].parse::<f64>().unwrap());
        }
    }
    cols
}

/// Compares dq signals `(d, q)` derived from the phase columns `abc` with the file's
/// `(d_ref, q_ref)` over `rows`: returns (max |Δx_dq|, max of |Δx_dq| / rounding bound).
///
/// Every value was written with 7 significant digits. The bound adds the rotation by the
/// rounded angle, `|x_dq| n_p q7(θ_m)` (≈ 2e-6 rad at |θ_m| ≈ 3: 2.4e-5 A at 12 A), plus
/// `|x_dq| q7(θ_e)` where the file's dq values were computed from a logged, rounded θ_e
/// (gym-electric-motor's noisy file), the phase rounding through Clarke,
/// `≤ 1.8 max_x q7(x_x)`, and the rounding of the dq values themselves, `2 q7(|x_dq|)`.
fn dq_error(
    (d, q): (&[f64], &[f64]),
    (d_ref, q_ref): (&[f64], &[f64]),
    abc: &[Vec<f64>],
    theta_m: &[f64],
    theta_e_ref: Option<&[f64]>,
    n_p: f64,
    rows: std::ops::Range<usize>,
) -> (f64, f64) {
    rows.map(|k| {
        let x = d_ref[k].hypot(q_ref[k]);
        let err = (d[k] - d_ref[k]).hypot(q[k] - q_ref[k]);
        let angle = n_p * q7(theta_m[k]) + theta_e_ref.map_or(0.0, |th| q7(th[k]));
        let phase = abc.iter().map(|c| q7(c[k])).fold(0.0, f64::max);
        (err, err / (x * angle + 1.8 * phase + 2.0 * q7(x) + 1e-15))
    })
    .fold((0.0, 0.0), |(a, b), (e, r)| (f64::max(a, e), f64::max(b, r)))
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn phases_reproduce_motulator_dq_signals() {
    crate::common::require_shared!();
    let dq = read_csv(&*SERVO, 4, &CsvOptions::default()).unwrap();
    let opts = CsvOptions { source: DqSource::Phases, ..CsvOptions::default() };
    let ph = read_csv(&*SERVO, 4, &opts).unwrap();
    assert_eq!(ph.len(), dq.len());
    let (dq, ph) = (DqView::try_new(&dq).unwrap(), DqView::try_new(&ph).unwrap());
    let n = dq.len();
    let th = dq.theta_m().unwrap();
    let raw = raw_columns(&SERVO, &["ia", "ib", "ic", "ua", "ub", "uc"]);
    let (i_abc, u_abc) = raw.split_at(3);
    let (e_i, r_i) = dq_error((ph.i_d(), ph.i_q()), (dq.i_d(), dq.i_q()), i_abc, th, None, 4.0, 0..n);
    // The last row has no w_m[k+1]: its period speed is w_m[k]; compare the others.
    let (e_u, r_u) = dq_error(
        (ph.terminal_voltage().unwrap().0, ph.terminal_voltage().unwrap().1),
        (dq.terminal_voltage().unwrap().0, dq.terminal_voltage().unwrap().1),
        u_abc,
        th,
        None,
        4.0,
        0..n - 1,
    );
    let u_mag: Vec<f64> = (0..n)
        .map(|k| dq.terminal_voltage().unwrap().0[k].hypot(dq.terminal_voltage().unwrap().1[k]))
        .collect();
    let u_max = u_mag.iter().copied().fold(0.0, f64::max);
    let e_u_rel = (0..n - 1)
        .filter(|&k| u_mag[k] > 1.0)
        .map(|k| {
            (ph.terminal_voltage().unwrap().0[k] - dq.terminal_voltage().unwrap().0[k])
                .hypot(ph.terminal_voltage().unwrap().1[k] - dq.terminal_voltage().unwrap().1[k])
                / u_mag[k]
        })
        .fold(0.0, f64::max);
    eprintln!(
        "phases -> dq (motulator): max |Δi_dq| = {e_i:.3e} A ({r_i:.3} of the rounding bound), \
         max |Δu_dq| = {e_u:.3e} V ({r_u:.3} of the rounding bound, |u|max = {u_max:.1} V), \
         max |Δu|/|u| (|u| > 1 V) = {e_u_rel:.3e}"
    );
    assert!(r_i <= 1.0, "current error {e_i:e} A exceeds the 7-digit rounding bound ({r_i})");
    assert!(e_i < 3e-5, "current error {e_i:e} A");
    assert!(r_u <= 1.0, "voltage error {e_u:e} V exceeds the 7-digit rounding bound ({r_u})");
    assert!(e_u < 5e-6 * u_max, "voltage error {e_u:e} V of {u_max} V");
    assert!(e_u_rel < 5e-6, "relative voltage error {e_u_rel:e}");
    // Without the stator-hold factor the error is of order φ/2 = n_p w h / 2 (≈ 0.06 at
    // 280 rad/s): the factor is what makes the match.
    let worst = (0..n - 1)
        .filter(|&k| u_mag[k] > 1.0)
        .map(|k| {
            let (fr, fi) = stator_hold_mean_factor(4.0 * 0.5 * (dq.w_m()[k] + dq.w_m()[k + 1]) * 1e-4);
            let (d, q) = (ph.terminal_voltage().unwrap().0[k], ph.terminal_voltage().unwrap().1[k]);
            // Undo the factor: divide by (fr + j fi).
            let m2 = fr * fr + fi * fi;
            let (d0, q0) = ((d * fr + q * fi) / m2, (q * fr - d * fi) / m2);
            (d0 - dq.terminal_voltage().unwrap().0[k]).hypot(q0 - dq.terminal_voltage().unwrap().1[k])
                / u_mag[k]
        })
        .fold(0.0, f64::max);
    eprintln!("without the stator-hold factor: max |Δu|/|u| = {worst:.3e}");
    assert!(worst > 1e-2, "uncorrected error {worst:e} should be large");
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn phases_reproduce_gem_noisy_currents() {
    crate::common::require_shared!();
    // GEM's phase voltages come from a dq-held voltage, so only the currents are compared.
    let dq = read_csv(&*GEM_NOISY, 4, &CsvOptions::default()).unwrap();
    let ph =
        read_csv(&*GEM_NOISY, 4, &CsvOptions { source: DqSource::Phases, ..CsvOptions::default() }).unwrap();
    let (dq, ph) = (DqView::try_new(&dq).unwrap(), DqView::try_new(&ph).unwrap());
    let th = dq.theta_m().unwrap();
    let mut raw = raw_columns(&GEM_NOISY, &["ia", "ib", "ic", "theta_e"]);
    let theta_e = raw.pop().unwrap();
    let (e_i, r_i) =
        dq_error((ph.i_d(), ph.i_q()), (dq.i_d(), dq.i_q()), &raw, th, Some(&theta_e), 4.0, 0..dq.len());
    let i_max = dq.i_d().iter().zip(dq.i_q()).map(|(d, q)| d.hypot(*q)).fold(0.0, f64::max);
    eprintln!(
        "phases -> dq (GEM noisy): max |Δi_dq| = {e_i:.3e} A ({r_i:.3} of the rounding bound, |i|max {i_max:.1} A)"
    );
    assert!(r_i <= 1.0, "current error {e_i:e} A exceeds the 7-digit rounding bound ({r_i})");
    assert!(e_i < 5e-6 * i_max, "current error {e_i:e} A of {i_max} A");
}

// ---------------------------------------------------------------- unit options

#[test]
fn unit_options_convert_to_si() {
    // rpm, electrical frame, degrees, RMS currents and voltages, renamed columns.
    let n = MIN_SAMPLES + 4;
    let n_p = 3;
    let mut s = String::from("time, Vd ,Vq,Id,Iq,speed_rpm,angle_deg,Vd_ref,Vq_ref,extra\n");
    for k in 0..n {
        let t = 2.5e-4 * k as f64;
        s.push_str(&format!("{t},10,-20,1,2,3000,{},5,6,whatever\n", 90 + k));
    }
    let p = temp_file("units", s.as_bytes());
    let mut opts = CsvOptions {
        speed_unit: SpeedUnit::Rpm,
        speed_frame: Frame::Electrical,
        angle_unit: AngleUnit::Deg,
        current_scale: Scale::Rms,
        voltage_scale: Scale::Rms,
        ..CsvOptions::default()
    };
    let c = &mut opts.columns;
    (c.t, c.u_d, c.u_q, c.i_d, c.i_q) = ("time".into(), "Vd".into(), "Vq".into(), "Id".into(), "Iq".into());
    (c.w_m, c.theta_m, c.u_d_ref, c.u_q_ref) =
        ("speed_rpm".into(), "angle_deg".into(), "Vd_ref".into(), "Vq_ref".into());
    let e = read_csv(&p, n_p, &opts).unwrap();
    let e = DqView::try_new(&e).unwrap();
    assert_eq!(e.len(), n);
    assert_relative_eq!(e.h(), 2.5e-4, max_relative = 1e-12);
    // 3000 rpm electrical = 100π rad/s electrical = 100π/3 rad/s mechanical.
    assert_relative_eq!(e.w_m()[0], 100.0 * PI / 3.0, max_relative = 1e-12);
    assert_relative_eq!(e.theta_m().unwrap()[2], (92.0_f64).to_radians() / 3.0, max_relative = 1e-12);
    assert_relative_eq!(e.terminal_voltage().unwrap().0[0], 10.0 * SQRT_2, max_relative = 1e-12);
    assert_relative_eq!(e.terminal_voltage().unwrap().1[0], -20.0 * SQRT_2, max_relative = 1e-12);
    assert_relative_eq!(e.i_d()[0], SQRT_2, max_relative = 1e-12);
    assert_relative_eq!(e.i_q()[0], 2.0 * SQRT_2, max_relative = 1e-12);
    assert_relative_eq!(e.u_dq_ref().unwrap().1[0], 6.0 * SQRT_2, max_relative = 1e-12);
    // Plain and gzip give the same; the gzip file has no `.gz` name: detection is by content.
    let gz = temp_path("units-gz", "csv");
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    std::io::Write::write_all(&mut enc, s.as_bytes()).unwrap();
    std::fs::write(&gz, enc.finish().unwrap()).unwrap();
    let e_gz = read_csv(&gz, n_p, &opts).unwrap();
    assert_eq!(DqView::try_new(&e_gz).unwrap().to_signals(), e.to_signals());
    std::fs::remove_file(p).ok();
    std::fs::remove_file(gz).ok();
}

#[test]
fn options_round_trip_through_serde() {
    let opts = CsvOptions { speed_unit: SpeedUnit::Rpm, source: DqSource::Phases, ..CsvOptions::default() };
    let json = serde_json::to_string(&opts).unwrap();
    let back: CsvOptions = serde_json::from_str(&json).unwrap();
    assert_eq!(back, opts);
    // Missing fields take their defaults.
    let partial: CsvOptions = serde_json::from_str(r#"{"columns": {"w_m": "speed"}}"#).unwrap();
    assert_eq!(partial.columns.w_m, "speed");
    assert_eq!(partial.columns.t, "t");
    assert_eq!(partial.speed_unit, SpeedUnit::RadPerSec);
}

// ---------------------------------------------------------------- transforms

#[test]
fn clarke_park_known_values() {
    // A phase peak of 2 at angle 0: i_a = 2, i_b = i_c = −1 → (α, β) = (2, 0).
    let (al, be) = clarke(2.0, -1.0, -1.0);
    assert_relative_eq!(al, 2.0, epsilon = 1e-15);
    assert_relative_eq!(be, 0.0, epsilon = 1e-15);
    // At θ_e = π/2 the α axis is −q.
    let (d, q) = park(al, be, PI / 2.0);
    assert_relative_eq!(d, 0.0, epsilon = 1e-15);
    assert_relative_eq!(q, -2.0, epsilon = 1e-15);
    assert_eq!(stator_hold_mean_factor(0.0), (1.0, 0.0));
    // Series and closed form agree across the switch at 1e-8.
    let (a, b) = stator_hold_mean_factor(0.99e-8);
    let (c, d) = stator_hold_mean_factor(1.01e-8);
    assert_relative_eq!(a, c, max_relative = 1e-15);
    assert_relative_eq!(b / 0.99e-8, d / 1.01e-8, max_relative = 1e-12);
    let (c, d) = stator_hold_mean_factor(0.5);
    assert_relative_eq!(c, 0.5_f64.sin() / 0.5, max_relative = 1e-15);
    assert_relative_eq!(d, -(1.0 - 0.5_f64.cos()) / 0.5, max_relative = 1e-14);
}

#[test]
fn phase_transforms_check_lengths() {
    let a = [0.0; 4];
    let err = currents_to_dq(&a, &a, &a[..3], &a, 4).unwrap_err();
    assert!(matches!(&err, Error::LengthMismatch { column, .. } if column == "ic"), "{err:?}");
    let err = stator_held_voltages_to_dq(&a, &a, &a, &a, &a[..2], 1e-4, 4).unwrap_err();
    assert!(matches!(&err, Error::LengthMismatch { column, .. } if column == "w_m"), "{err:?}");
    assert!(err.to_string().contains("w_m"));
}

proptest! {
    #[test]
    fn park_inverse_park_is_identity(d in -1e3..1e3f64, q in -1e3..1e3f64, th in -100.0..100.0f64) {
        let (al, be) = inverse_park(d, q, th);
        let (d2, q2) = park(al, be, th);
        prop_assert!((d2 - d).abs() <= 1e-12 * (1.0 + d.abs() + q.abs()));
        prop_assert!((q2 - q).abs() <= 1e-12 * (1.0 + d.abs() + q.abs()));
        // Park preserves the magnitude.
        prop_assert!((al.hypot(be) - d.hypot(q)).abs() <= 1e-12 * (1.0 + d.hypot(q)));
    }

    #[test]
    fn clarke_inverse_clarke_is_identity(x_a in -1e3..1e3f64, x_b in -1e3..1e3f64, al in -1e3..1e3f64, be in -1e3..1e3f64) {
        let scale = 1e-12 * (1.0 + x_a.abs() + x_b.abs());
        // Balanced set: x_c = −x_a − x_b.
        let x_c = -x_a - x_b;
        let (a, b) = clarke(x_a, x_b, x_c);
        let (ya, yb, yc) = inverse_clarke(a, b);
        prop_assert!((ya - x_a).abs() <= scale && (yb - x_b).abs() <= scale && (yc - x_c).abs() <= scale);
        let (al2, be2) = clarke(inverse_clarke(al, be).0, inverse_clarke(al, be).1, inverse_clarke(al, be).2);
        let s2 = 1e-12 * (1.0 + al.abs() + be.abs());
        prop_assert!((al2 - al).abs() <= s2 && (be2 - be).abs() <= s2);
    }

    #[test]
    fn try_new_never_panics(
        h in prop_oneof![Just(f64::NAN), Just(0.0), Just(-1.0), Just(f64::INFINITY), 1e-6..1.0f64],
        n_p in 0u32..5,
        lens in proptest::collection::vec(0usize..40, 5),
        x in prop_oneof![Just(f64::NAN), Just(f64::NEG_INFINITY), any::<f64>()],
        at in 0usize..40,
        opt in proptest::option::of(0usize..40),
    ) {
        let mk = |n: usize| (0..n).map(|k| if k == at { x } else { k as f64 }).collect::<Vec<f64>>();
        let s = Signals {
            u_d: mk(lens[0]), u_q: mk(lens[1]), i_d: mk(lens[2]), i_q: mk(lens[3]), w_m: mk(lens[4]),
            theta_m: opt.map(mk), u_d_ref: None, u_q_ref: opt.map(mk),
        };
        let t: Vec<f64> = (0..lens[0]).map(|k| k as f64 * 1e-3).collect();
        let _ = Experiment::try_new("garbage", h, s.clone().into_channels());
        let _ = s.clone().into_experiment("garbage", h);
        if let Ok(e) = Experiment::try_from_time("garbage", "t", &t, s.into_channels()) {
            // n_p now lives in the model: preparing never panics either (n_p = 0 is an error).
            let m = greybox::pmsm::PmsmSpm::new(n_p, greybox::pmsm::VoltageHold::Stator);
            let _ = greybox::model::GreyBoxModel::prepare(&m, &e);
        }
    }

    #[test]
    fn read_csv_never_panics_on_random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400), gz in any::<bool>()) {
        let data = if gz {
            let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            std::io::Write::write_all(&mut enc, &bytes).unwrap();
            enc.finish().unwrap()
        } else { bytes };
        let p = temp_file("bytes", &data);
        let r = read_default(&p);
        std::fs::remove_file(&p).ok();
        prop_assert!(r.is_err());
        let phases = CsvOptions { source: DqSource::Phases, ..CsvOptions::default() };
        let p = temp_file("bytes-ph", b"t,w_m,theta_m,ia,ib,ic,ua,ub,uc\n");
        std::fs::write(&p, [b"t,w_m,theta_m,ia,ib,ic,ua,ub,uc\n".as_slice(), &data].concat()).unwrap();
        let _ = read_csv(&p, 2, &phases);
        std::fs::remove_file(&p).ok();
    }

    #[test]
    fn read_csv_never_panics_on_random_floats(
        rows in proptest::collection::vec(
            proptest::collection::vec(prop_oneof![Just(f64::NAN), Just(f64::INFINITY), any::<f64>(), -10.0..10.0f64], 9),
            0..40),
        n_p in 0u32..4,
        phases in any::<bool>(),
    ) {
        let mut s = String::from("t,ud,uq,id,iq,w_m,theta_m,ia,ib\n");
        for r in &rows {
            let line: Vec<String> = r.iter().map(f64::to_string).collect();
            s.push_str(&line.join(","));
            s.push('\n');
        }
        let p = temp_file("floats", s.as_bytes());
        let opts = CsvOptions { source: if phases { DqSource::Phases } else { DqSource::Dq }, ..CsvOptions::default() };
        let _ = read_csv(&p, n_p, &opts);
        std::fs::remove_file(&p).ok();
    }

    #[test]
    fn read_csv_never_panics_on_valid_time_with_random_values(
        vals in proptest::collection::vec(prop_oneof![Just(f64::NAN), Just(f64::INFINITY), any::<f64>()], 17 * 20),
        n_p in 1u32..4,
    ) {
        let mut s = String::from("t,w_m,theta_m,ia,ib,ic,ua,ub,uc,ud,uq,id,iq,ud_ref,uq_ref,x,y\n");
        for (k, r) in vals.chunks(17).enumerate() {
            let mut line = vec![format!("{}", k as f64 * 1e-4)];
            line.extend(r[1..].iter().map(f64::to_string));
            s.push_str(&line.join(","));
            s.push('\n');
        }
        let p = temp_file("valid-time", s.as_bytes());
        for source in [DqSource::Dq, DqSource::Phases] {
            let _ = read_csv(&p, n_p, &CsvOptions { source, ..CsvOptions::default() });
        }
        std::fs::remove_file(&p).ok();
    }
}

// ---------------------------------------------------------------- errors, one each

#[test]
fn error_missing_file() {
    let p = temp_path("does-not-exist", "csv.gz");
    let err = read_default(&p).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err:?}");
    assert!(err.to_string().contains(&*p.to_string_lossy()), "{err}");
}

#[test]
fn error_empty_file() {
    let p = temp_file("empty", b"");
    let err = read_default(&p).unwrap_err();
    assert!(matches!(err, Error::TooShort { len: 0, .. }), "{err:?}");
    let stem = p.file_stem().unwrap().to_string_lossy().into_owned();
    assert!(err.to_string().contains(&stem), "{err}");
    std::fs::remove_file(p).ok();
}

#[test]
fn error_header_only() {
    let p = temp_file("header-only", b"t,ud,uq,id,iq,w_m\n");
    let err = read_default(&p).unwrap_err();
    assert!(matches!(err, Error::TooShort { len: 0, .. }), "{err:?}");
    assert!(err.to_string().contains("header-only"), "{err}");
    std::fs::remove_file(p).ok();
}

#[test]
fn error_too_few_rows() {
    let p = temp_file("short", valid_rows(MIN_SAMPLES - 1).as_bytes());
    let err = read_default(&p).unwrap_err();
    assert!(
        matches!(err, Error::TooShort { len, min, .. } if len == MIN_SAMPLES - 1 && min == MIN_SAMPLES),
        "{err:?}"
    );
    assert!(err.to_string().contains("short"), "{err}");
    std::fs::remove_file(&p).ok();
    // Exactly MIN_SAMPLES rows is enough.
    let p = temp_file("just-enough", valid_rows(MIN_SAMPLES).as_bytes());
    assert_eq!(read_default(&p).unwrap().len(), MIN_SAMPLES);
    std::fs::remove_file(p).ok();
}

/// `valid_rows(20)` with data row `row`'s field `col` replaced by `text`.
fn with_field(row: usize, col: usize, text: &str) -> String {
    let mut lines: Vec<String> = valid_rows(20).lines().map(str::to_string).collect();
    let mut fields: Vec<String> = lines[row + 1].split(',').map(str::to_string).collect();
    fields[col] = text.to_string();
    lines[row + 1] = fields.join(",");
    lines.join("\n") + "\n"
}

#[test]
fn error_nan() {
    let p = temp_file("nan", with_field(7, 3, "nan").as_bytes());
    let err = read_default(&p).unwrap_err();
    assert!(
        matches!(&err, Error::NonFinite { column, row: 7, value } if column == "id" && value.is_nan()),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(msg.contains("`id`") && msg.contains("row 7"), "{msg}");
    std::fs::remove_file(p).ok();
}

#[test]
fn error_inf() {
    let p = temp_file("inf", with_field(12, 5, "-inf").as_bytes());
    let err = read_default(&p).unwrap_err();
    assert!(
        matches!(&err, Error::NonFinite { column, row: 12, value } if column == "w_m" && *value == f64::NEG_INFINITY),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(msg.contains("`w_m`") && msg.contains("row 12"), "{msg}");
    std::fs::remove_file(p).ok();
}

#[test]
fn error_nan_names_remapped_and_phase_columns() {
    // A remapped column is named as in the file.
    let text = with_field(3, 1, "NaN").replace("t,ud,", "t,Vd,");
    let p = temp_file("nan-remap", text.as_bytes());
    let mut opts = CsvOptions::default();
    opts.columns.u_d = "Vd".into();
    let err = read_csv(&p, 4, &opts).unwrap_err();
    assert!(matches!(&err, Error::NonFinite { column, row: 3, .. } if column == "Vd"), "{err:?}");
    std::fs::remove_file(p).ok();
    // With DqSource::Phases a NaN is reported in its phase column, not a derived dq one.
    let mut s = String::from("t,w_m,theta_m,ia,ib,ic,ua,ub,uc\n");
    for k in 0..20 {
        let ib = if k == 9 { "nan".to_string() } else { "0.5".into() };
        s.push_str(&format!("{},1,0.1,1,{ib},-1.5,2,-1,-1\n", k as f64 * 1e-3));
    }
    let p = temp_file("nan-phase", s.as_bytes());
    let err = read_csv(&p, 4, &CsvOptions { source: DqSource::Phases, ..CsvOptions::default() }).unwrap_err();
    assert!(matches!(&err, Error::NonFinite { column, row: 9, .. } if column == "ib"), "{err:?}");
    std::fs::remove_file(p).ok();
}

#[test]
fn error_ragged_row() {
    let mut text = valid_rows(20);
    text = text.replacen("\n0.005000,", "\n0.005000,99,", 1);
    let p = temp_file("ragged", text.as_bytes());
    let err = read_default(&p).unwrap_err();
    // Header = line 1, row k = line k + 2: t = 0.005 is row 5, line 7.
    assert!(matches!(err, Error::Csv { line: 7, .. }), "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains("line 7") && msg.contains(&*p.to_string_lossy()) && msg.contains("7 fields"),
        "{msg}"
    );
    std::fs::remove_file(p).ok();
}

#[test]
fn error_unparsable_number() {
    let p = temp_file("unparsable", with_field(4, 2, "1.2.3").as_bytes());
    let err = read_default(&p).unwrap_err();
    assert!(matches!(err, Error::Csv { line: 6, .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("`uq`") && msg.contains("1.2.3") && msg.contains("line 6"), "{msg}");
    std::fs::remove_file(&p).ok();
    // An unused column may hold anything.
    let text = valid_rows(20).replace("w_m\n", "w_m,note\n").replace(",10\n", ",10,n/a\n");
    let p = temp_file("unused-text", text.as_bytes());
    assert_eq!(read_default(&p).unwrap().len(), 20);
    std::fs::remove_file(p).ok();
}

#[test]
fn error_non_uniform_time() {
    // Drop the sample at t = 0.010 s (row 10).
    let text: String =
        valid_rows(30).lines().filter(|l| !l.starts_with("0.010000,")).map(|l| format!("{l}\n")).collect();
    let p = temp_file("dropped", text.as_bytes());
    let err = read_default(&p).unwrap_err();
    assert!(matches!(&err, Error::NonUniformTime { column, .. } if column == "t"), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("`t`") && msg.contains("row"), "{msg}");
    std::fs::remove_file(p).ok();
}

#[test]
fn error_missing_column() {
    let text = valid_rows(20).replace("t,ud,uq,id,iq,w_m", "t,ud,uq,id,iq,speed");
    let p = temp_file("missing-col", text.as_bytes());
    let err = read_default(&p).unwrap_err();
    assert!(matches!(&err, Error::MissingColumn { column, .. } if column == "w_m"), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("`w_m`") && msg.contains("speed") && msg.contains(&*p.to_string_lossy()), "{msg}");
    // Phases need the phase columns and theta_m.
    let err = read_csv(&p, 4, &CsvOptions { source: DqSource::Phases, ..CsvOptions::default() }).unwrap_err();
    assert!(matches!(&err, Error::MissingColumn { column, .. } if column == "ia"), "{err:?}");
    std::fs::remove_file(p).ok();
}

#[test]
fn error_zero_pole_pairs() {
    // Checked before the file is opened: even a missing file reports the pole pairs.
    let err = read_csv(temp_path("np0", "csv"), 0, &CsvOptions::default()).unwrap_err();
    assert!(matches!(err.domain(), Some(PmsmError::InvalidPolePairs { n_p: 0 })), "{err:?}");
    assert!(err.to_string().contains("n_p"), "{err}");
}

fn signals(n: usize) -> Signals {
    let v = vec![1.0; n];
    Signals { u_d: v.clone(), u_q: v.clone(), i_d: v.clone(), i_q: v.clone(), w_m: v, ..Signals::default() }
}

#[test]
fn error_try_new_length_mismatch() {
    let mut s = signals(20);
    s.i_q.pop();
    let err = s.into_experiment("x", 1e-4).unwrap_err();
    assert!(
        matches!(&err, Error::LengthMismatch { column, expected: 20, found: 19 } if column == "iq"),
        "{err:?}"
    );
    assert!(err.to_string().contains("`iq`"), "{err}");
    let mut s = signals(20);
    s.theta_m = Some(vec![0.0; 21]);
    let err = s.into_experiment("x", 1e-4).unwrap_err();
    assert!(matches!(&err, Error::LengthMismatch { column, .. } if column == "theta_m"), "{err:?}");
}

#[test]
fn error_try_new_bad_sample_time() {
    for h in [0.0, -1e-4, f64::NAN, f64::INFINITY] {
        let err = signals(20).into_experiment("x", h).unwrap_err();
        assert!(matches!(err, Error::InvalidSampleTime { .. }), "{err:?}");
        assert!(err.to_string().contains("sample time h"), "{err}");
    }
}

// ---------------------------------------------------------------- generic data layer

#[test]
fn generic_minimum_is_one_sample_pmsm_minimum_is_eight() {
    // A generic experiment needs one sample; none is TooShort with min 1.
    let e = Experiment::try_new("one", 1e-3, vec![Channel::new("x", "", vec![1.0])]).unwrap();
    assert_eq!(e.len(), 1);
    assert_eq!(greybox::data::MIN_SAMPLES, 1);
    let err = Experiment::try_new("none", 1e-3, vec![Channel::new("x", "", vec![])]).unwrap_err();
    assert!(matches!(&err, Error::TooShort { name, len: 0, min: 1 } if name == "none"), "{err:?}");
    let err = Experiment::try_new("no-channel", 1e-3, vec![]).unwrap_err();
    assert!(matches!(err, Error::TooShort { len: 0, min: 1, .. }), "{err:?}");
    // The PMSM view still wants MIN_SAMPLES = 8.
    assert_eq!(MIN_SAMPLES, 8);
    let short = Experiment::try_new("short", 1e-3, signals(MIN_SAMPLES - 1).into_channels()).unwrap();
    let err = DqView::try_new(&short).unwrap_err();
    assert!(
        matches!(&err, Error::TooShort { name, len, min } if name == "short" && *len == MIN_SAMPLES - 1 && *min == MIN_SAMPLES),
        "{err:?}"
    );
    let err = signals(MIN_SAMPLES - 1).into_experiment("short", 1e-3).unwrap_err();
    assert!(matches!(err, Error::TooShort { min: 8, .. }), "{err:?}");
}

#[test]
fn missing_channel_names_the_channel_and_the_experiment() {
    let e = Experiment::try_new(
        "bench",
        1e-3,
        vec![Channel::new("u", "V", vec![1.0, 2.0]), Channel::new("i", "A", vec![0.1, 0.2])],
    )
    .unwrap();
    assert_eq!(e.channel("u").unwrap(), [1.0, 2.0]);
    assert!(e.get("temperature").is_none());
    let err = e.channel("temperature").unwrap_err();
    match &err {
        Error::MissingChannel { experiment, channel, available } => {
            assert_eq!(experiment, "bench");
            assert_eq!(channel, "temperature");
            assert_eq!(available, "u, i");
        }
        other => panic!("expected MissingChannel, got {other:?}"),
    }
    let msg = err.to_string();
    assert!(msg.contains("`bench`") && msg.contains("`temperature`") && msg.contains("u, i"), "{msg}");
}

#[test]
fn duplicate_channel_is_an_error() {
    let err = Experiment::try_new(
        "dup",
        1e-3,
        vec![
            Channel::new("u", "V", vec![1.0, 2.0]),
            Channel::new("i", "A", vec![0.1, 0.2]),
            Channel::new("u", "V", vec![3.0, 4.0]),
        ],
    )
    .unwrap_err();
    assert!(
        matches!(&err, Error::DuplicateChannel { experiment, channel } if experiment == "dup" && channel == "u"),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(msg.contains("`dup`") && msg.contains("`u`"), "{msg}");
    // `with_channel` replaces a channel of the same name instead.
    let e = Experiment::try_new("dup", 1e-3, vec![Channel::new("u", "V", vec![1.0, 2.0])]).unwrap();
    let e = e.with_channel(Channel::new("u", "V", vec![5.0, 6.0])).unwrap();
    assert_eq!(e.channels().len(), 1);
    assert_eq!(e.channel("u").unwrap(), [5.0, 6.0]);
}

#[test]
fn generic_csv_reads_a_non_motor_experiment() {
    // A thermal bench log: time in ms, heater power in kW (scaled to W), a temperature
    // read as it is, a column the spec ignores and an optional one the file lacks.
    let mut text = String::from("time_ms,P_kW,T_C,comment\n");
    for k in 0..5 {
        text.push_str(&format!("{},{},{},note{k}\n", 10 * k, 0.5 * k as f64, 20.0 + k as f64));
    }
    let p = temp_file("thermal", text.as_bytes());
    let mut humidity = ColumnMap::new("RH", "humidity", "");
    humidity.required = false;
    let mut power = ColumnMap::new("P_kW", "p", "W");
    power.scale = 1e3;
    let spec = CsvSpec {
        time: "time_ms".into(),
        time_scale: 1e-3,
        columns: vec![power, ColumnMap::new("T_C", "temperature", "degC"), humidity],
        ..CsvSpec::default()
    };
    let e = greybox::data::read_csv(&p, &spec).unwrap();
    let stem = p.file_stem().unwrap().to_string_lossy().into_owned();
    assert_eq!(e.name(), stem);
    assert_eq!(e.len(), 5);
    assert_relative_eq!(e.h(), 1e-2, max_relative = 1e-12);
    let names: Vec<&str> = e.channels().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["p", "temperature"]);
    assert_eq!(e.get("p").unwrap().unit, "W");
    assert_eq!(e.channel("p").unwrap(), [0.0, 500.0, 1000.0, 1500.0, 2000.0]);
    assert_eq!(e.channel("temperature").unwrap(), [20.0, 21.0, 22.0, 23.0, 24.0]);
    // Not a motor log: the PMSM view names the first dq channel it lacks.
    let err = DqView::try_new(&e).unwrap_err();
    assert!(matches!(&err, Error::MissingChannel { channel, .. } if channel == "ud"), "{err:?}");
    // A required column missing from the header is named.
    let spec = CsvSpec { columns: vec![ColumnMap::new("flow", "flow", "m3/s")], ..spec };
    let err = greybox::data::read_csv(&p, &spec).unwrap_err();
    assert!(matches!(&err, Error::MissingColumn { column, .. } if column == "flow"), "{err:?}");
    std::fs::remove_file(p).ok();
}

#[test]
fn dq_view_without_iq_is_a_missing_channel() {
    let mut channels = signals(20).into_channels();
    channels.retain(|c| c.name != "iq");
    let e = Experiment::try_new("no-iq", 1e-4, channels).unwrap();
    let err = DqView::try_new(&e).unwrap_err();
    match &err {
        Error::MissingChannel { experiment, channel, available } => {
            assert_eq!(experiment, "no-iq");
            assert_eq!(channel, "iq");
            assert_eq!(available, "ud, uq, id, w_m");
        }
        other => panic!("expected MissingChannel, got {other:?}"),
    }
    assert!(err.to_string().contains("`iq`"), "{err}");
}

proptest::proptest! {
    /// The peak current is the largest `hypot` of any sample, exactly, whatever the scale
    /// (down to where the squares underflow and up to where they overflow).
    #[test]
    fn the_peak_current_is_the_largest_hypot(
        scale in proptest::sample::select(vec![1e-170, 3e-161, 1e-157, 1e-3, 1.0, 1e3, 1e153, 1e154, 1e300]),
        values in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 16..80),
    ) {
        let i_d: Vec<f64> = values.iter().map(|v| v.0 * scale).collect();
        let i_q: Vec<f64> = values.iter().map(|v| v.1 * scale).collect();
        let n = i_d.len();
        let e = Experiment::try_new(
            "peak",
            1e-4,
            vec![
                Channel::new("ud", "V", vec![0.0; n]),
                Channel::new("uq", "V", vec![0.0; n]),
                Channel::new("id", "A", i_d.clone()),
                Channel::new("iq", "A", i_q.clone()),
                Channel::new("w_m", "rad/s", vec![0.0; n]),
            ],
        )
        .unwrap();
        let direct = i_d.iter().zip(&i_q).map(|(d, q)| d.hypot(*q)).fold(0.0, f64::max);
        let peak = greybox::pmsm::DqView::try_new(&e).unwrap().peak_current();
        proptest::prop_assert_eq!(peak.to_bits(), direct.to_bits());
    }
}

/// `decimate` keeps every k-th sample from the first, multiplies h by k and keeps the start
/// time; 0 is refused.
#[test]
fn decimate_keeps_point_samples() {
    let x: Vec<f64> = (0..10).map(f64::from).collect();
    let e = greybox::Experiment::try_new("e", 0.5, vec![greybox::Channel::new("x", "A", x)]).unwrap();
    let d = e.decimate(3).unwrap();
    assert_eq!(d.channel("x").unwrap(), &[0.0, 3.0, 6.0, 9.0]);
    assert_eq!(d.h(), 1.5);
    assert_eq!(d.name(), "e /3");
    assert!(e.decimate(0).unwrap_err().to_string().contains("factor"));
}
