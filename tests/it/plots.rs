//! Plots (`report::plot`, feature `plot`) and the residual export (`report::residuals`):
//! the SVG is written atomically with labelled axes and legends, long logs are decimated
//! for drawing, and the residual CSV reads back with residual = measured − simulated.
//! Runs on the shipped `data/sample.csv.gz`.

use crate::common::TempDir;
use greybox::Experiment;
use greybox::data::{ColumnMap, CsvSpec, read_csv};
use greybox::pmsm::{CsvOptions, PmsmFit, fit_pmsm, read_log};
use greybox::report::Comparison;
use greybox::report::write_residuals_csv;
use std::path::Path;
use std::sync::OnceLock;

/// The shipped sample log (servo SPM, 4 pole pairs).
fn sample() -> Experiment {
    read_log(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/sample.csv.gz"), &CsvOptions::default())
        .unwrap()
}

/// The sample fitted once, with its comparisons at the estimate.
fn fitted() -> &'static (Experiment, PmsmFit, Vec<Comparison>) {
    static FIT: OnceLock<(Experiment, PmsmFit, Vec<Comparison>)> = OnceLock::new();
    FIT.get_or_init(|| {
        let log = sample();
        let fit = fit_pmsm(std::slice::from_ref(&log), &crate::common::pmsm_options(4)).unwrap();
        let comparisons = fit.comparisons(std::slice::from_ref(&log)).unwrap();
        (log, fit, comparisons)
    })
}

/// A fresh, empty folder for one test, removed when the guard drops.
fn folder(tag: &str) -> TempDir {
    TempDir::new(&format!("plots-{tag}"))
}

#[test]
fn simulated_outputs_match_the_fit() {
    let (log, fit, comparisons) = fitted();
    assert_eq!(comparisons.len(), 1);
    let c = &comparisons[0];
    assert_eq!(c.outputs, ["id", "iq"]);
    assert_eq!(c.units, ["A", "A"]);
    assert_eq!(c.len(), log.len());
    assert_eq!(c.measured(0), log.channel("id").unwrap());
    // Simulated from the estimated initial state, the fit percentage is the report's.
    for (a, b) in c.metrics.fit_percent.iter().zip(&fit.fit.fit_percent) {
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    }
    // The trace: the start, then one row per iteration, ending at the estimate.
    let free: Vec<f64> = fit.parameters.iter().filter(|p| !p.fixed).map(|p| p.value).collect();
    assert_eq!(fit.parameter_trace.len() as u64, fit.solver.iterations + 1);
    let last = fit.parameter_trace.last().unwrap();
    for (t, v) in last.iter().zip(&free) {
        assert!((t / v - 1.0).abs() < 1e-3, "{t} vs {v}");
    }
    assert!(fit.to_json().contains("\"parameter_trace\""));
}

#[cfg(feature = "plot")]
mod svg {
    use super::*;
    use greybox::online::{TrackRun, TrackTruth, track_svg};
    use greybox::report::plot::{self, Context};

    /// Points drawn by every `<polyline>` of an SVG.
    fn polyline_points(svg: &str) -> Vec<usize> {
        svg.split("<polyline")
            .skip(1)
            .map(|p| {
                let pts = p.split("points=\"").nth(1).and_then(|s| s.split('"').next()).unwrap_or("");
                pts.split_whitespace().count()
            })
            .collect()
    }

    #[test]
    fn fit_plot_has_labelled_axes_and_legends() {
        let (log, fit, comparisons) = fitted();
        let speed = [log.channel("w_m").unwrap()];
        let ctx = Context { name: "w_m", unit: "rad/s, mechanical", per_log: &speed };
        let svg = plot::fit_svg(fit, comparisons, Some(&ctx)).unwrap();
        let dir = folder("fit");
        let path = dir.join("fit.svg");
        plot::write_svg(&path, &svg).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("<svg"), "{}", &text[..80]);
        assert!(text.trim_end().ends_with("</svg>"));
        for label in [
            "t [s]",
            "w_m [rad/s, mechanical]",
            "id [A]",
            "iq [A]",
            "ε id [A]",
            "lag τ [samples]",
            "r(τ) [-]",
            "iteration",
            "θ / θ̂ − 1 [-]",
            "95 % interval relative to the estimate [%]",
            // legend entries
            "id measured",
            "id simulated",
            "w_m measured",
            "±2σ, σ =",
            "±1.96/√N",
            "rms residual",
            "r_s",
            "l_s",
            "k_e",
            // the estimates with their units, SI-prefixed
            "r_s = ",
            "mΩ",
            "mH",
            "mV s/rad",
            "lags outside ±1.96/√N",
        ] {
            assert!(text.contains(label), "the fit plot lacks `{label}`");
        }
        // Only the SVG is in the folder: no temporary file left.
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["fit.svg"]);
    }

    #[test]
    fn a_failing_plot_leaves_no_file() {
        let (_, fit, comparisons) = fitted();
        let dir = folder("atomic");
        // Nothing to draw: an error before anything is written.
        let err = plot::fit_svg(fit, &[], None).unwrap_err();
        assert!(err.to_string().contains("plot"), "{err}");
        // A context signal of the wrong length names the signal.
        let short = [&[0.0; 3][..]];
        let ctx = Context { name: "w_m", unit: "rad/s", per_log: &short };
        let err = plot::fit_svg(fit, comparisons, Some(&ctx)).unwrap_err();
        assert!(err.to_string().contains("w_m"), "{err}");
        // An unwritable path: the error names it, and neither the file nor a temporary is left.
        let svg = plot::fit_svg(fit, comparisons, None).unwrap();
        let missing = dir.join("no/such/folder/fit.svg");
        let err = plot::write_svg(&missing, &svg).unwrap_err();
        assert!(err.to_string().contains("no/such/folder/fit.svg"), "{err}");
        // The target is a folder: the rename fails after the temporary was written.
        let target = dir.join("taken.svg");
        std::fs::create_dir(&target).unwrap();
        std::fs::write(target.join("keep"), "x").unwrap();
        assert!(plot::write_svg(&target, &svg).is_err());
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["taken.svg"], "a temporary file was left behind");
        // An existing plot is kept intact by a failing write.
        let good = dir.join("good.svg");
        plot::write_svg(&good, &svg).unwrap();
        assert!(plot::write_svg(&good.join("child.svg"), "<svg/>").is_err());
        assert_eq!(std::fs::read_to_string(&good).unwrap(), svg);
    }

    #[test]
    fn long_logs_are_decimated_for_drawing() {
        // 400 000 samples of a noisy output: the plot draws at most two points per pixel column.
        let n = 400_000;
        let (mut y, mut y_hat) = (Vec::with_capacity(2 * n), Vec::with_capacity(2 * n));
        let mut rng = crate::common::Rng(0x9e37_79b9_7f4a_7c15);
        for k in 0..n {
            let s = (k as f64 * 1e-4).sin();
            y.extend([s + 0.01 * rng.normal(), 2.0 * s + 0.01 * rng.normal()]);
            y_hat.extend([s, 2.0 * s]);
        }
        let outputs = vec!["id".to_string(), "iq".to_string()];
        let metrics = greybox::estimate::metrics(&outputs, &y, &y_hat, 3, 25).unwrap();
        let c = Comparison {
            experiment: "long".into(),
            h: 1e-4,
            t0: 0.0,
            outputs,
            units: vec!["A".into(), "A".into()],
            y,
            y_hat,
            metrics,
            counted: Vec::new(),
            horizon: None,
        };
        let svg = plot::compare_svg(std::slice::from_ref(&c), None).unwrap();
        let lines = polyline_points(&svg);
        assert!(!lines.is_empty());
        let widest = 1600;
        assert!(lines.iter().all(|&p| p <= 2 * widest + 2), "{lines:?}");
        let total: usize = lines.iter().sum();
        assert!(total < 6 * 2 * widest, "{total} points drawn for {n} samples");
        assert!(svg.len() < 2_000_000, "{} bytes", svg.len());
        // decimate_min_max itself: at most 2 points per column, extremes kept.
        let t: Vec<f64> = (0..n).map(|k| k as f64).collect();
        let v = c.measured(0);
        let d = plot::decimate_min_max(&t, &v, 500);
        assert!(d.len() <= 1000);
        let max = v.iter().copied().fold(f64::MIN, f64::max);
        assert!(d.iter().any(|p| p.1 == max));
    }

    #[test]
    fn compare_and_track_plots() {
        let (log, _, comparisons) = fitted();
        let svg = plot::compare_svg(comparisons, None).unwrap();
        for label in ["Validation", "id [A]", "r(τ) [-]", "Fit per log", "sample: id"] {
            assert!(svg.contains(label), "the compare plot lacks `{label}`");
        }
        let config =
            greybox::online::MrasConfig { n_p: 4, l_s: 4.5e-3, k_e0: 0.3, r_s0: 0.5, ..Default::default() };
        let tr = greybox::online::track(log, &config).unwrap();
        let truth = TrackTruth::constant(0.5389, 0.9);
        let svg = track_svg(&[TrackRun { name: "sample", trajectory: &tr, truth: Some(&truth) }]).unwrap();
        for label in [
            "K_e [V s/rad]",
            "K_t [N m/A]",
            "R_s [Ω]",
            "t [s]",
            "truth 0.53890 V s/rad",
            "R_s estimate, sample",
        ] {
            assert!(svg.contains(label), "the track plot lacks `{label}`");
        }
        assert!(polyline_points(&svg).iter().all(|&p| p <= 2 * 1600 + 2));
        assert!(track_svg(&[]).is_err());
    }
}

#[test]
fn residual_csv_round_trips() {
    let (log, _, comparisons) = fitted();
    let dir = folder("residuals");
    let path = dir.join("res.csv");
    write_residuals_csv(&path, comparisons).unwrap();
    let columns = ["id", "iq"]
        .iter()
        .flat_map(|o| ["measured", "simulated", "residual"].map(|s| format!("{o}_{s}")))
        .map(|c| ColumnMap::new(&c, &c, "A"))
        .collect();
    let back = read_csv(&path, &CsvSpec { columns, ..CsvSpec::default() }).unwrap();
    assert_eq!(back.len(), log.len());
    assert!((back.h() - log.h()).abs() < 1e-12);
    let c = &comparisons[0];
    for (i, o) in ["id", "iq"].iter().enumerate() {
        let m = back.channel(&format!("{o}_measured")).unwrap();
        let s = back.channel(&format!("{o}_simulated")).unwrap();
        let r = back.channel(&format!("{o}_residual")).unwrap();
        assert_eq!(m, log.channel(o).unwrap(), "{o}: measured, bit for bit");
        assert_eq!(s, &c.simulated(i)[..], "{o}: simulated, bit for bit");
        assert!(
            m.iter().zip(s).zip(r).all(|((m, s), r)| *r == m - s),
            "{o}: residual ≠ measured − simulated"
        );
    }
}

#[test]
fn residual_csv_of_several_logs_has_a_log_column() {
    let (_, _, comparisons) = fitted();
    let mut other = comparisons[0].clone();
    other.experiment = "second".into();
    let both = [comparisons[0].clone(), other];
    let dir = folder("residuals-many");
    let path = dir.join("res.csv");
    write_residuals_csv(&path, &both).unwrap();
    let mut rdr = csv::Reader::from_path(&path).unwrap();
    let header: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(header[..3], ["log", "t", "id_measured"]);
    let logs: Vec<String> = rdr.records().map(|r| r.unwrap()[0].to_string()).collect();
    let n = both[0].len();
    assert_eq!(logs.len(), 2 * n);
    assert!(logs[..n].iter().all(|l| l == "sample") && logs[n..].iter().all(|l| l == "second"));
    // Errors: nothing to write, or a folder that does not exist (named).
    assert!(write_residuals_csv(&dir.join("x.csv"), &[]).is_err());
    let err = write_residuals_csv(&dir.join("missing/x.csv"), &both).unwrap_err();
    assert!(err.to_string().contains("missing/x.csv"), "{err}");
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, ["res.csv"]);
}

#[test]
#[cfg(feature = "cli")]
fn cli_writes_plot_and_residuals_and_names_a_bad_path() {
    let dir = folder("cli");
    let (plot, res) = (dir.join("fit.svg"), dir.join("res.csv"));
    let out = crate::errors::greybox(&[
        "fit",
        "data/sample.csv.gz",
        "-p",
        "4",
        "-q",
        "--plot",
        plot.to_str().unwrap(),
        "--residuals",
        res.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read_to_string(&plot).unwrap().starts_with("<svg"));
    assert!(
        std::fs::read_to_string(&res)
            .unwrap()
            .starts_with("t,id_measured,id_simulated,id_residual,iq_measured")
    );
    // A plot into a missing folder fails before the fit, naming the flag and the path.
    let bad = dir.join("nope/fit.svg");
    let out = crate::errors::greybox(&[
        "fit",
        "data/sample.csv.gz",
        "-p",
        "4",
        "-q",
        "--plot",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("plot") && err.contains("nope"), "{err}");
    // --method ls cannot simulate its estimate: refused, naming the flag.
    let out = crate::errors::greybox(&[
        "fit",
        "data/sample.csv.gz",
        "-p",
        "4",
        "--method",
        "ls",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("--plot"));
}
