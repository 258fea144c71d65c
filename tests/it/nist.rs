//! NIST StRD's 27 nonlinear regression problems (NIST/ITL Statistical Reference Datasets,
//! public domain; the files in `tests/data/nist/` as NIST publishes them) through the
//! generic estimator as a user fits a curve: each problem a static grey-box model without
//! sensitivities (finite differences), fitted by [`greybox::estimate::fit`] from NIST's two
//! starts with the default options but the solver.
//!
//! Accuracy is the log relative error of each estimate against NIST's certified value,
//! `LRE = −log₁₀(|b − b*| / |b*|)` (McCullough, *The American Statistician* 53 (1999)
//! 149–159), capped at 11 (the certified digits); a problem counts as solved where the
//! smallest LRE over its parameters is at least 6 and the solver reports convergence.
//! `cargo test --release --test it nist:: -- --nocapture` prints the table and writes it to
//! `target/nist_table.md`.

use greybox::estimate::{PemOptions, SolverKind, fit};
use greybox::model::{GreyBoxModel, Parameter, Signal};
use greybox::{Channel, Experiment};
use std::f64::consts::PI;
use std::fmt::Write as _;

/// A NIST model `y = f(b, x₁, x₂)` (x₂ only for Nelson).
type Curve = fn(&[f64], f64, f64) -> f64;

/// The 27 models by dataset name (NIST's model descriptions in each file).
fn curve(name: &str) -> Curve {
    match name {
        "Bennett5" => |b, x, _| b[0] * (b[1] + x).powf(-1.0 / b[2]),
        "BoxBOD" | "Misra1a" => |b, x, _| b[0] * (1.0 - (-b[1] * x).exp()),
        "Chwirut1" | "Chwirut2" => |b, x, _| (-b[0] * x).exp() / (b[1] + b[2] * x),
        "DanWood" => |b, x, _| b[0] * x.powf(b[1]),
        "ENSO" => |b, x, _| {
            let (a, c, d) = (2.0 * PI * x / 12.0, 2.0 * PI * x / b[3], 2.0 * PI * x / b[6]);
            b[0] + b[1] * a.cos()
                + b[2] * a.sin()
                + b[4] * c.cos()
                + b[5] * c.sin()
                + b[7] * d.cos()
                + b[8] * d.sin()
        },
        "Eckerle4" => |b, x, _| (b[0] / b[1]) * (-0.5 * ((x - b[2]) / b[1]).powi(2)).exp(),
        "Gauss1" | "Gauss2" | "Gauss3" => |b, x, _| {
            b[0] * (-b[1] * x).exp()
                + b[2] * (-(x - b[3]).powi(2) / (b[4] * b[4])).exp()
                + b[5] * (-(x - b[6]).powi(2) / (b[7] * b[7])).exp()
        },
        "Hahn1" | "Thurber" => |b, x, _| {
            (b[0] + b[1] * x + b[2] * x * x + b[3] * x.powi(3))
                / (1.0 + b[4] * x + b[5] * x * x + b[6] * x.powi(3))
        },
        "Kirby2" => |b, x, _| (b[0] + b[1] * x + b[2] * x * x) / (1.0 + b[3] * x + b[4] * x * x),
        "Lanczos1" | "Lanczos2" | "Lanczos3" => {
            |b, x, _| b[0] * (-b[1] * x).exp() + b[2] * (-b[3] * x).exp() + b[4] * (-b[5] * x).exp()
        }
        "MGH09" => |b, x, _| b[0] * (x * x + x * b[1]) / (x * x + x * b[2] + b[3]),
        "MGH10" => |b, x, _| b[0] * (b[1] / (x + b[2])).exp(),
        "MGH17" => |b, x, _| b[0] + b[1] * (-x * b[3]).exp() + b[2] * (-x * b[4]).exp(),
        "Misra1b" => |b, x, _| b[0] * (1.0 - (1.0 + b[1] * x / 2.0).powi(-2)),
        "Misra1c" => |b, x, _| b[0] * (1.0 - (1.0 + 2.0 * b[1] * x).powf(-0.5)),
        "Misra1d" => |b, x, _| b[0] * b[1] * x / (1.0 + b[1] * x),
        "Nelson" => |b, x1, x2| b[0] - b[1] * x1 * (-b[2] * x2).exp(),
        "Rat42" => |b, x, _| b[0] / (1.0 + (b[1] - b[2] * x).exp()),
        "Rat43" => |b, x, _| b[0] / (1.0 + (b[1] - b[2] * x).exp()).powf(1.0 / b[3]),
        "Roszman1" => |b, x, _| b[0] - b[1] * x - (b[2] / (x - b[3])).atan() / PI,
        other => panic!("no NIST model {other}"),
    }
}

/// One dataset: its starts, certified values and observations.
struct Dataset {
    name: String,
    starts: [Vec<f64>; 2],
    certified: Vec<f64>,
    /// `(y, x₁, x₂)`; Nelson's y as `ln y`, the response of its model.
    rows: Vec<(f64, f64, f64)>,
}

/// Reads a NIST StRD file: the lines `bK = start1 start2 certified sd`, and the
/// observations after the second line that begins with `Data:`.
fn read(path: &std::path::Path) -> Dataset {
    let text = std::fs::read_to_string(path).expect("a NIST file");
    let name = path.file_stem().and_then(|s| s.to_str()).expect("a name").to_string();
    let (mut s1, mut s2, mut certified) = (Vec::new(), Vec::new(), Vec::new());
    let mut rows = Vec::new();
    let mut data_lines = 0;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with("Data:") {
            data_lines += 1;
            continue;
        }
        if data_lines >= 2 {
            let v: Vec<f64> = t.split_whitespace().filter_map(|w| w.parse().ok()).collect();
            match v.as_slice() {
                [y, x] => rows.push((*y, *x, 0.0)),
                [y, x1, x2] => rows.push((y.ln(), *x1, *x2)),
                _ => {}
            }
        } else if let Some((lhs, rhs)) = t.split_once('=')
            && lhs.trim().starts_with('b')
            && lhs.trim()[1..].parse::<usize>().is_ok()
        {
            let v: Vec<f64> = rhs.split_whitespace().filter_map(|w| w.parse().ok()).collect();
            if let [a, b, c, _] = v.as_slice() {
                s1.push(*a);
                s2.push(*b);
                certified.push(*c);
            }
        }
    }
    Dataset { name, starts: [s1, s2], certified, rows }
}

/// The datasets in `tests/data/nist/`, in file-name order.
fn datasets() -> Vec<Dataset> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/nist");
    let mut paths: Vec<_> = std::fs::read_dir(dir)
        .expect("tests/data/nist")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "dat"))
        .collect();
    paths.sort();
    paths.iter().map(|p| read(p)).collect()
}

/// A NIST model as a user's static grey-box model (finite-difference sensitivities).
struct Nist {
    name: String,
    params: Vec<Parameter>,
    f: Curve,
}

impl GreyBoxModel for Nist {
    type Inputs = (Vec<f64>, Vec<f64>);
    type Coefficients = Vec<f64>;
    fn name(&self) -> &str {
        &self.name
    }
    fn n_states(&self) -> usize {
        0
    }
    fn outputs(&self) -> Vec<Signal> {
        vec![Signal::new("y", "")]
    }
    fn input_channels(&self) -> Vec<String> {
        vec!["x1".into(), "x2".into()]
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn prepare(&self, e: &Experiment) -> greybox::Result<Self::Inputs> {
        Ok((e.channel("x1")?.to_vec(), e.channel("x2")?.to_vec()))
    }
    fn coefficients(&self, b: &[f64], _: &Self::Inputs) -> greybox::Result<Vec<f64>> {
        Ok(b.to_vec())
    }
    fn step(&self, _: &Vec<f64>, _: &Self::Inputs, _: usize, _: &[f64], _: &mut [f64]) {}
    fn output(&self, b: &Vec<f64>, (x1, x2): &Self::Inputs, k: usize, _: &[f64], y: &mut [f64]) {
        y[0] = (self.f)(b, x1[k], x2[k]);
    }
}

/// The smallest LRE over the estimates `b` against `certified` (capped at 11).
fn lre(b: &[f64], certified: &[f64]) -> f64 {
    b.iter()
        .zip(certified)
        .map(|(b, c)| match (b - c).abs() / c.abs() {
            e if e > 0.0 => (-e.log10()).min(11.0),
            _ => 11.0,
        })
        .fold(f64::INFINITY, f64::min)
}

/// One fit: the smallest LRE (0 for a fit that fails), convergence, trust (converged and
/// no untrusted warning), evaluations.
fn run(d: &Dataset, start: usize, solver: SolverKind) -> (f64, bool, bool, u64) {
    let params = d.starts[start]
        .iter()
        .enumerate()
        .map(|(k, v)| Parameter::free(&format!("b{}", k + 1), "", *v))
        .collect();
    let model = Nist { name: d.name.clone(), params, f: curve(&d.name) };
    let col = |f: fn(&(f64, f64, f64)) -> f64| d.rows.iter().map(f).collect::<Vec<_>>();
    let channels = vec![
        Channel::new("y", "", col(|r| r.0)),
        Channel::new("x1", "", col(|r| r.1)),
        Channel::new("x2", "", col(|r| r.2)),
    ];
    let e = Experiment::try_new(&d.name, 1.0, channels).expect("a table");
    let options = PemOptions { solver, ..Default::default() };
    match fit(&model, &[e], &d.starts[start], &options) {
        Ok(f) => {
            let b: Vec<f64> = f.parameters.iter().map(|p| p.value).collect();
            (lre(&b, &d.certified), f.solver.success, f.trusted(), f.solver.evaluations)
        }
        Err(_) => (0.0, false, false, 0),
    }
}

/// Both solvers at the default options on the 54 runs: the table, and no fit trusted that
/// is wrong (smallest LRE below 4: not the certified minimum; BoxBOD from start 1 converges
/// on a plateau, and the trust gate's `poor_fit` says so).
#[test]
fn nist_strd_from_both_starts() {
    let sets = datasets();
    assert_eq!(sets.len(), 27, "the 27 NIST StRD nonlinear regression files");
    let solvers = [SolverKind::Lm, SolverKind::TrustRegion];
    let mut table = String::from(
        "| problem | start | lm: LRE (evaluations) | trust-region: LRE (evaluations) |\n|---|---|---|---|\n",
    );
    let mut solved = [0; 2];
    let mut wrong = Vec::new();
    for d in &sets {
        assert_eq!(d.certified.len(), d.starts[0].len(), "{}: starts and certified values", d.name);
        assert!(!d.rows.is_empty(), "{}: observations", d.name);
        for start in 0..2 {
            let _ = write!(table, "| {} | {} |", d.name, start + 1);
            for (k, solver) in solvers.iter().enumerate() {
                let (lre, success, trusted, evals) = run(d, start, *solver);
                if success && lre >= 6.0 {
                    solved[k] += 1;
                }
                if trusted && lre < 4.0 {
                    wrong.push(format!("{} start {} {solver:?}: LRE {lre:.1}", d.name, start + 1));
                }
                let flag = match (success, trusted) {
                    (false, _) => ", not converged",
                    (true, false) => ", untrusted",
                    (true, true) => "",
                };
                let _ = write!(table, " {lre:.1} ({evals}{flag}) |");
            }
            table.push('\n');
        }
    }
    let _ = writeln!(
        table,
        "\nsolved to 6 digits and converged: lm {} of 54, trust-region {} of 54",
        solved[0], solved[1]
    );
    println!("{table}");
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/target");
    std::fs::create_dir_all(dir).expect("target directory");
    std::fs::write(format!("{dir}/nist_table.md"), &table).expect("write target/nist_table.md");
    assert!(wrong.is_empty(), "trusted away from the certified values: {wrong:?}");
    // What the solvers reach at the defaults (500 iterations; 2026-11-30, docs/performance.md),
    // kept from falling back: the misses are BoxBOD from start 1 (a plateau, untrusted) and
    // ENSO (LRE 5.1) for both, MGH10 and MGH17 from start 1 for Levenberg-Marquardt, Bennett5
    // from start 1 for the trust region (iteration limit).
    assert!(solved[0] >= 49 && solved[1] >= 50, "solved: {solved:?}");
}
