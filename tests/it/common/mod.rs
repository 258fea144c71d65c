//! Shared test helpers: the development logs and their ground truth, synthetic records.
#![allow(dead_code)]

use greybox::Experiment;
use greybox::model::{GreyBoxModel, Prepared};
pub use greybox::pmsm::DqSignals as Signals;
use greybox::pmsm::{CsvOptions, PmsmFitOptions};
use greybox::simulate::SimOptions;
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

/// Path of a file in the development logs' folder (see [`shared_dir`]), as a string.
pub fn shared_file(name: &str) -> String {
    shared_dir().join(name).to_string_lossy().into_owned()
}

/// First statement of a test that reads the development logs: without their folder it
/// prints one line on stderr naming the test and returns, so the test passes as skipped.
/// `require_shared!(value)` returns `value` instead of `()` (e.g. `Ok(())` in a `main`).
#[allow(unused_macros)] // the examples that include this file need not use it
macro_rules! require_shared {
    () => {
        $crate::common::require_shared!(())
    };
    ($ret:expr) => {
        if $crate::common::shared().is_none() {
            fn here() {}
            let name = std::any::type_name_of_val(&here);
            let name = name.strip_suffix("::here").unwrap_or(name);
            // One write to the real stderr: `eprintln!` would be captured by the test harness.
            let line = format!(
                "skipped {name}: {} not found (development logs are not part of the repository; \
                 set GREYBOX_SHARED_DATA to their folder)\n",
                $crate::common::shared_dir().display()
            );
            let _ = std::io::Write::write_all(&mut std::io::stderr(), line.as_bytes());
            return $ret;
        }
    };
}
#[allow(unused_imports)] // the examples that include this file need not use it
pub(crate) use require_shared;

/// Path of a log in the development logs' folder (../shared/data unless
/// `GREYBOX_SHARED_DATA` says otherwise).
pub fn data(name: &str) -> PathBuf {
    shared_dir().join(name)
}

/// Ground truth of a log, from its JSON.
#[derive(Debug, Clone)]
pub struct Truth {
    pub r_s: f64,
    pub l_d: f64,
    pub l_q: f64,
    pub k_e: f64,
    pub psi_f: f64,
    pub n_p: u32,
    pub salient: bool,
}

pub fn truth(stem: &str) -> Truth {
    let path = data(&format!("{stem}.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!("{}: {e}; the data-driven tests need the development logs in ../shared/data beside the repository", path.display())
    });
    let v: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    let f = |k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{stem}.json: {k}"));
    let (l_d, l_q) = (f("Ld_H"), f("Lq_H"));
    Truth {
        r_s: f("Rs_ohm"),
        l_d,
        l_q,
        k_e: f("Ke_project_Vs_per_rad_mech"),
        psi_f: f("psi_f_Vs"),
        n_p: v["np_pole_pairs"].as_u64().expect("n_p") as u32,
        salient: v["Ls_H"].is_null(),
    }
}

/// Reads a log with its truth's pole-pair number.
pub fn load(stem: &str) -> (Experiment, Truth) {
    let t = truth(stem);
    let e =
        greybox::pmsm::read_log(data(&format!("{stem}.csv.gz")), &CsvOptions::default()).expect("log reads");
    (e, t)
}

/// A PMSM experiment from dq signals sampled every h [s].
pub fn experiment(name: &str, h: f64, signals: Signals) -> Experiment {
    signals.into_experiment(name, h).expect("valid signals")
}

/// Reads a PMSM log with `n_p` pole pairs and the given options (any log, not only the
/// development ones).
pub fn read(
    path: impl AsRef<std::path::Path>,
    n_p: u32,
    options: &CsvOptions,
) -> greybox::Result<Experiment> {
    greybox::pmsm::read_log(path, &CsvOptions { pole_pairs: Some(n_p), ..options.clone() })
}

/// Default PMSM fit options for a motor with `n_p` pole pairs.
pub fn pmsm_options(n_p: u32) -> PmsmFitOptions {
    PmsmFitOptions::new(n_p)
}

/// Simulated outputs with the default options.
pub fn sim<M: GreyBoxModel>(
    model: &M,
    prep: &Prepared<M::Inputs>,
    theta: &[f64],
) -> greybox::Result<Vec<f64>> {
    greybox::simulate::simulate(model, prep, theta, &SimOptions::default())
}

/// Two short records of the drive simulator's exp3 moves (0.3 s and 0.2 s), the SPM
/// model at the stator hold, and a start off the truth (R_s +10 %, L −10 %), so that the
/// residuals and the gradient there are not zero: the setting of the tests that compare
/// the prediction-error problem's passes.
pub fn spm_records_off_truth() -> (Experiment, Experiment, greybox::pmsm::PmsmSpm, [f64; 3]) {
    use greybox::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
    let record = |seconds: f64| {
        let cfg = DriveConfig { duration: seconds, ..scenario("exp3", SPM_MOTOR).unwrap() };
        simulate_drive(&cfg).unwrap().experiment
    };
    let m = greybox::pmsm::PmsmSpm::new(SPM_MOTOR.n_p, greybox::pmsm::VoltageHold::Stator);
    let start = [1.1 * SPM_MOTOR.r_s, 0.9 * SPM_MOTOR.l_d, SPM_MOTOR.k_e()];
    (record(0.3), record(0.2), m, start)
}

/// Relative error.
pub fn rel(est: f64, truth: f64) -> f64 {
    ((est - truth) / truth).abs()
}

/// Small deterministic generator (xorshift64*), so tests need no RNG crate.
pub struct Rng(pub u64);
impl Rng {
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

/// Exciting inputs: random voltage steps plus a back-EMF-like term and a speed sweep that
/// reverses, with n samples at step h.
pub fn exciting_signals(n: usize, h: f64, w_max: f64, u_amp: f64, k_e: f64, rng: &mut Rng) -> Signals {
    let mut s = Signals::default();
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

/// Replaces the currents of `signals` by the model's own simulation at θ from rest.
pub fn simulate_into<M: GreyBoxModel>(model: &M, theta: &[f64], h: f64, mut signals: Signals) -> Experiment {
    let e = experiment("synthetic", h, signals.clone());
    let prep: Prepared<M::Inputs> = Prepared::new(model, &e).expect("prepare");
    let y = sim(model, &prep, theta).expect("simulate");
    let ny = model.n_outputs();
    signals.i_d = (0..e.len()).map(|k| y[k * ny]).collect();
    signals.i_q = (0..e.len()).map(|k| y[k * ny + 1]).collect();
    experiment("synthetic", h, signals)
}

/// A fresh directory under the system temp folder, removed with everything in it when the
/// guard drops (also when the test panics). The name is `greybox-{prefix}-{pid}-{n}` with a
/// per-process counter `n`, so tests running in parallel never share a directory.
pub struct TempDir(PathBuf);

impl TempDir {
    pub fn new(prefix: &str) -> TempDir {
        static COUNTER: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("greybox-{prefix}-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create temp dir");
        TempDir(dir)
    }
    pub fn path(&self) -> &std::path::Path {
        &self.0
    }
    pub fn join(&self, name: impl AsRef<std::path::Path>) -> PathBuf {
        self.0.join(name)
    }
}

impl std::ops::Deref for TempDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::path::Path> for TempDir {
    fn as_ref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for TempDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A path `greybox-{prefix}-{pid}-{n}-{name}` under the system temp folder (nothing is
/// created; `name` keeps its extension), removed when the guard drops, whether something
/// made it a file or a directory. Dereferences to the path. [`TempFile::in_dir`] keeps
/// `name` as it is, in a fresh [`TempDir`] of its own.
pub struct TempFile(PathBuf, Option<TempDir>);

impl TempFile {
    pub fn new(prefix: &str, name: &str) -> TempFile {
        static COUNTER: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        TempFile(
            std::env::temp_dir().join(format!("greybox-{prefix}-{}-{n}-{name}", std::process::id())),
            None,
        )
    }
    /// The path `name` in a fresh directory (see [`TempDir::new`]), removed with it.
    pub fn in_dir(prefix: &str, name: &str) -> TempFile {
        let dir = TempDir::new(prefix);
        TempFile(dir.join(name), Some(dir))
    }
    pub fn path(&self) -> &std::path::Path {
        &self.0
    }
}

impl std::ops::Deref for TempFile {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::path::Path> for TempFile {
    fn as_ref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for TempFile {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if self.0.is_dir() {
            let _ = std::fs::remove_dir_all(&self.0);
        } else {
            let _ = std::fs::remove_file(&self.0);
        }
    }
}
