//! How speed weighting shifts what a fit listens to (thesis 5.2.2, eq. 5.11):
//! `cargo run --release --example weighting`.
//!
//! The servo log `servo_spm_moves_idinj` (n_p 4, stator hold; back-and-forth moves at
//! 30/100/190/280 rad/s with d-current injections) and its noisy copy are fitted with
//! uniform weights, a low-speed weight (w0 = 50 rad/s), a high-speed weight
//! (w0 = 150 rad/s) and a band (150–300 rad/s, floor 0.05). The table shows the
//! estimates, their parametric error index (the change of the parameter, the others
//! re-optimised, that doubles the weighted E²; small = well determined) and, for
//! comparison only, the error against the log's ground truth. The error index does not
//! change when every weight is scaled, so the rows compare directly.

#[path = "../tests/it/common/mod.rs"]
mod common;

use common::{load, rel};
use greybox::estimate::SpeedShape;
use greybox::estimate::{PemOptions, WeightingKind};
use greybox::pmsm::{HoldChoice, PmsmFitOptions, channel, fit_pmsm};

fn main() -> greybox::Result<()> {
    common::require_shared!(Ok(()));
    let speed = |shape| WeightingKind::Speed { channel: channel::W_M.into(), shape };
    let weightings = [
        ("uniform", WeightingKind::Uniform),
        ("low speed, w0 50", speed(SpeedShape::LowSpeed { w0: 50.0 })),
        ("high speed, w0 150", speed(SpeedShape::HighSpeed { w0: 150.0 })),
        ("band 150-300, 0.05", speed(SpeedShape::Band { lo: 150.0, hi: 300.0, floor: 0.05 })),
    ];
    for stem in ["servo_spm_moves_idinj", "servo_spm_moves_idinj_noisy"] {
        let (log, truth) = load(stem);
        let truths = [truth.r_s, truth.l_d, truth.k_e];
        println!("\n{stem}: {} samples, h = {} s, n_p = {}", log.len(), log.h(), truth.n_p);
        println!(
            "{:<19} | {:>12} {:>9} {:>9} | {:>12} {:>9} {:>9} | {:>12} {:>9} {:>9} | {:>4}",
            "weighting",
            "r_s [Ω]",
            "index %",
            "rel err",
            "l_s [H]",
            "index %",
            "rel err",
            "k_e [Vs/rad]",
            "index %",
            "rel err",
            "iter"
        );
        for (label, weighting) in weightings.clone() {
            let opts = PmsmFitOptions {
                hold: HoldChoice::Stator,
                pem: PemOptions { weighting, ..Default::default() },
                ..PmsmFitOptions::new(truth.n_p)
            };
            let fit = fit_pmsm(std::slice::from_ref(&log), &opts)?;
            let mut line = format!("{label:<19}");
            for (name, t) in ["r_s", "l_s", "k_e"].iter().zip(truths) {
                let p = fit.parameter(name).expect("estimated");
                line += &format!(
                    " | {:>12.6e} {:>9.2e} {:>9.2e}",
                    p.value,
                    p.error_index_percent,
                    rel(p.value, t)
                );
            }
            let flag = if fit.solver.success { "" } else { " (not converged)" };
            println!("{line} | {:>4}{flag}", fit.solver.iterations);
        }
    }
    Ok(())
}
