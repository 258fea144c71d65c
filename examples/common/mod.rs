//! Helpers shared by the examples (not an example itself: Cargo builds only `examples/*.rs`
//! and `examples/*/main.rs`): the development logs and their ground truth, a small
//! deterministic random generator and synthetic PMSM records.
//!
//! The examples keep their own copy instead of including `tests/it/common/mod.rs`, so that
//! they do not break whenever the test helpers change.
#![allow(dead_code)]

use greybox::model::{GreyBoxModel, Prepared};
use greybox::pmsm::{CsvOptions, DqSignals, read_log};
use greybox::simulate::{SimOptions, simulate};
use greybox::{Experiment, Result};
use std::path::PathBuf;

/// Folder of the development logs: `$GREYBOX_SHARED_DATA` if set, else `../shared/data`
/// beside the repository. The logs are not part of the repository.
pub fn shared_dir() -> PathBuf {
    match std::env::var_os("GREYBOX_SHARED_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
    }
}

/// The folder of the development logs, if it exists.
pub fn shared() -> Option<PathBuf> {
    let dir = shared_dir();
    dir.is_dir().then_some(dir)
}

/// First statement of an example's `main` that reads the development logs: without their
/// folder it prints one line on stderr naming the example and returns `$ret` (exit code 0).
#[allow(unused_macros)] // not every example that includes this file skips
macro_rules! require_shared {
    ($ret:expr) => {
        if $crate::common::shared().is_none() {
            eprintln!(
                "skipped example {}: {} not found (development logs are not part of the repository; \
                 set GREYBOX_SHARED_DATA to their folder)",
                env!("CARGO_CRATE_NAME"),
                $crate::common::shared_dir().display()
            );
            return $ret;
        }
    };
}
#[allow(unused_imports)]
pub(crate) use require_shared;

/// Path of a file in the development logs' folder.
pub fn data(name: &str) -> PathBuf {
    shared_dir().join(name)
}

/// Ground truth of a development log, from its JSON.
#[derive(Debug, Clone)]
pub struct Truth {
    /// Stator resistance [Ω].
    pub r_s: f64,
    /// d-axis inductance [H].
    pub l_d: f64,
    /// q-axis inductance [H].
    pub l_q: f64,
    /// Back-EMF constant [V s/rad], mechanical.
    pub k_e: f64,
    /// Magnet flux [V s].
    pub psi_f: f64,
    /// Pole pairs.
    pub n_p: u32,
}

/// Reads `<stem>.json` of the development logs.
///
/// # Panics
/// If the file is missing or lacks a field (the examples call it after `require_shared!`).
pub fn truth(stem: &str) -> Truth {
    let path = data(&format!("{stem}.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let v: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    let f = |k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{stem}.json: {k}"));
    Truth {
        r_s: f("Rs_ohm"),
        l_d: f("Ld_H"),
        l_q: f("Lq_H"),
        k_e: f("Ke_project_Vs_per_rad_mech"),
        psi_f: f("psi_f_Vs"),
        n_p: v["np_pole_pairs"].as_u64().expect("n_p") as u32,
    }
}

/// Reads the development log `<stem>.csv.gz` and its truth.
///
/// # Errors
/// Those of [`read_log`].
pub fn load(stem: &str) -> Result<(Experiment, Truth)> {
    let t = truth(stem);
    let e = read_log(data(&format!("{stem}.csv.gz")), &CsvOptions::default())?;
    Ok((e, t))
}

/// Relative error `|est − truth|/|truth|`.
pub fn rel(est: f64, truth: f64) -> f64 {
    ((est - truth) / truth).abs()
}

/// Small deterministic generator (xorshift64*), so the examples need no RNG crate.
pub struct Rng(pub u64);

impl Rng {
    /// Next raw 64-bit value.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Exciting PMSM inputs, n samples at step h: random voltage steps every 40 samples plus
/// a back-EMF-like term, over a speed sweep to `w_max` [rad/s] that reverses; zero
/// currents (to be replaced by [`simulate_into`]).
pub fn exciting_signals(n: usize, h: f64, w_max: f64, u_amp: f64, k_e: f64, rng: &mut Rng) -> DqSignals {
    let mut s = DqSignals::default();
    let (mut ud, mut uq) = (0.0, 0.0);
    let f_w = 1.0 / (n as f64 * h); // one speed period over the record
    for k in 0..n {
        let t = k as f64 * h;
        if k % 40 == 0 {
            ud = u_amp * (2.0 * rng.uniform() - 1.0);
            uq = u_amp * (2.0 * rng.uniform() - 1.0);
        }
        let w = w_max * (2.0 * std::f64::consts::PI * f_w * t).sin() + 0.1 * w_max * (13.0 * t).cos();
        s.w_m.push(w);
        s.u_d.push(ud);
        s.u_q.push(uq + 0.8165 * k_e * w);
    }
    s.i_d = vec![0.0; n];
    s.i_q = vec![0.0; n];
    s
}

/// The record `signals` with its currents replaced by the PMSM model's own simulation at θ
/// from rest.
///
/// # Errors
/// Those of [`DqSignals::into_experiment`], [`Prepared::new`] and [`simulate`].
pub fn simulate_into<M: GreyBoxModel>(
    model: &M,
    theta: &[f64],
    h: f64,
    mut signals: DqSignals,
) -> Result<Experiment> {
    let e = signals.clone().into_experiment("synthetic", h)?;
    let prep = Prepared::new(model, &e)?;
    let y = simulate(model, &prep, theta, &SimOptions::default())?;
    let ny = model.n_outputs();
    signals.i_d = (0..e.len()).map(|k| y[k * ny]).collect();
    signals.i_q = (0..e.len()).map(|k| y[k * ny + 1]).collect();
    signals.into_experiment("synthetic", h)
}
