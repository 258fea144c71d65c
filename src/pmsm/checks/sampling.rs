//! The voltage-sampling check of a dynamic fit from the logged terminal voltage: is the
//! logged voltage the mean over each sample interval, as the exact sampled-data model holds
//! it, or a point sample?
//!
//! Why: the dynamic model takes `ud[k], uq[k]` as the voltage over `[t_k, t_k + h)` (a held
//! voltage, thesis 5.2; MODEL.md §3), which a drive's own log at its control rate is.
//! Telemetry that keeps every n-th row of a faster log holds point samples instead, and the
//! voltage moves within the interval. Every 20th row of the shared moves logs (500 Hz and
//! 250 Hz) was fitted by the dynamic model with `r_s` 3.1–3.3 % low at |z| 2.7–2.8 and exit
//! 0; the steady-state equations, which take the samples as points, put it within 0.003 %.
//!
//! The test: the fit is repeated with each interval's voltage taken as the mean of the
//! samples at its ends (the trapezoidal rule, what a point-sampled voltage tells of the
//! interval). On a held voltage that is a model error, and it can pass for a better fit only
//! through the voltage's own noise, which the mean of two samples weakens: white noise `n`
//! reaches the current through the model's response `g`, and for a first-order channel with
//! the pole `a = e^{−h/τ}` the mean's noise power there is `(1 + a)/2 ≥ 1/2` of the
//! sample's (its lag-1 autocovariance `a/(1 − a²)` against the variance `1/(1 − a²)`), for
//! rotations below a quarter electrical turn a sample, where a drive can control current at
//! all. So a mean squared residual below half the fit's ([`POINT_SAMPLE_RATIO`]) is not
//! noise: the voltage is point-sampled. On the shared logs: held voltages 10⁵–10⁷ times
//! worse by the trapezoid, 1 V of white voltage noise 0.99 times; every 20th and 40th row
//! 3.1–18 times better.
//!
//! Between the two, a trapezoid better than noise can make it at the log's sample time and
//! the fit's estimates ([`noise_bound`]) but by less than [`POINT_SAMPLE_RATIO`], the check
//! cannot tell: [`Sampling::Unclear`], and the dynamic fit is untrusted. The bound is one on
//! the expected squares at a fixed θ, so the refit's ratio must beat it by more than
//! [`RATIO_Z`] standard errors of the ratio (batch means of the squared residuals at the
//! fit's estimate), and the ratio at the estimate beat it too (two more simulations): the
//! refit gains from the noise beyond it. On a servo log with 1 V and 0.03 A of noise, 11 of
//! 100 seeds past the bound refitted, 3 at the estimate, none by 3 standard errors (the
//! ratio's about 0.0018, the excesses at most 0.0014); the point samples of every 10th row
//! of the shared noisy SPM log beat it by 5.9 and of the IPM log by 5.4.
//!
//! The refit runs only where the trapezoid already simulates the logs better at the fit's
//! own estimate (two simulations of each log's first [`PRETEST_SAMPLES`], no fit, no
//! statistics): on the every-20th/40th-row logs it does by
//! 1.2–2.7 times, on held voltages it is far worse, and a refit from an estimate where it is
//! worse would have to move the parameters by more than the hold's model error to win by
//! [`POINT_SAMPLE_RATIO`]. The default fit of a 72 000-sample log then costs no refit.

use crate::data::{Channel, Experiment};
use crate::estimate::FitResult;
use crate::model::{GreyBoxModel, Prepared};
use crate::pmsm::log::signals::channel::{U_D, U_Q, W_M};
use crate::pmsm::model::ipm::PmsmIpm;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::model::spm::PmsmSpm;
use crate::pmsm::options::{PmsmFitOptions, RefitReport};
use crate::simulate::{SimOptions, simulate};

/// How many times lower the trapezoid's mean squared residual must be than the fit's for
/// the voltage to be taken as point-sampled: white voltage noise on a held voltage cannot
/// make it more than 2 (the module's doc).
pub const POINT_SAMPLE_RATIO: f64 = 2.0;

/// Standard errors of the ratio at the fit's estimate ([`Squares::ratio_std_error`]) by
/// which it must exceed the noise bound for [`Sampling::Unclear`]: 3 (one-sided 0.13 % for
/// a normal ratio), the |z| the project judges by.
pub const RATIO_Z: f64 = 3.0;

/// Samples at the start of each log the simulations before the refit compare: enough for
/// the held voltage's advantage (10⁵ times on the shared logs) to show, a ninth of a
/// 72 000-sample log's cost.
pub const PRETEST_SAMPLES: usize = 8192;

/// After a dynamic fit `fit` of `experiments` from the terminal voltage, with the model's
/// `setup` (its pole pairs, hold and cable): `Some(text)` saying why the logged voltage
/// reads as point samples when the refit with the trapezoidal voltage (`refit`, from the
/// fit's estimate of the motor's parameters and at its hold, without setup checks) has a
/// mean squared residual [`POINT_SAMPLE_RATIO`] times lower. `None` otherwise: when the
/// trapezoid does not already simulate the logs better at the estimate, when a motor
/// parameter is missing from the fit, or when a simulation or the refit fails. (Not only after coloured residuals: every 25th row of the
/// shared IPM log passed the whiteness test with a fit of 85 %.)
pub(crate) fn point_sampled(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    fit: &FitResult,
    setup: PmsmSetup,
    refit: RefitReport<'_>,
) -> Option<Sampling> {
    // The motor's estimates in model order: the simulations' θ and the refit's start.
    let start: Option<Vec<f64>> =
        options.model.parameter_names().iter().map(|n| fit.parameter(n).map(|p| p.value)).collect();
    let start = start?;
    let heads: Option<Vec<Experiment>> =
        experiments.iter().map(|e| e.slice(0..e.len().min(PRETEST_SAMPLES)).ok()).collect();
    let heads = heads?;
    let head_trapezoid = trapezoid(&heads)?;
    let squares = |logs: &[Experiment], trapezoid: &[Experiment]| match options.model {
        MotorKind::Spm => squares_at(&PmsmSpm::from_setup(setup), logs, trapezoid, &start),
        MotorKind::Ipm => squares_at(&PmsmIpm::from_setup(setup), logs, trapezoid, &start),
    };
    let (held_head, mean_head) = squares(&heads, &head_trapezoid)?.sums();
    if mean_head >= held_head {
        return None;
    }
    let bound = noise_bound(&start, experiments, setup.n_p);
    let trapezoid = trapezoid(experiments)?;
    let options = PmsmFitOptions {
        start: Some(start.clone()),
        hold: setup.hold.into(),
        skip_setup_checks: true,
        ..options.clone()
    };
    let other = refit(&trapezoid, &options)?;
    let (held, mean) = (fit.fit.mse, other.fit.mse);
    if mean * POINT_SAMPLE_RATIO < held {
        return Some(Sampling::Points(format!(
            "the logged voltage reads as point samples, not as the mean over each sample interval the dynamic model \
             holds (telemetry kept from a faster log?): taking each interval's voltage as the mean of the samples at \
             its ends fits {:.1} times better (mean squared residual {mean:.4e} against {held:.4e}), which the \
             voltage's noise cannot do",
            held / mean
        )));
    }
    if mean * bound >= held {
        return None;
    }
    // The bound holds for the expected squares, at a fixed θ: the refit's ratio must exceed
    // it by more than RATIO_Z standard errors of the ratio (its sampling noise, read at the
    // estimate), and the ratio at the estimate exceed it too (the refit's own gain from the
    // noise is not bounded).
    let at_estimate = squares(experiments, &trapezoid)?;
    let (held_all, mean_all) = at_estimate.sums();
    let se = at_estimate.ratio_std_error();
    (held / mean - bound > RATIO_Z * se && mean_all * bound < held_all).then(|| {
        Sampling::Unclear(format!(
            "the logged voltage may be point samples, not the mean over each sample interval the dynamic model holds \
             (telemetry kept from a faster log?): taking each interval's voltage as the mean of the samples at its \
             ends fits {:.3} times better (mean squared residual {mean:.4e} against {held:.4e}; {:.3} times at these \
             estimates; the ratio's standard error {se:.1e}), more than a held voltage's noise can make it at this \
             sample time and these estimates ({bound:.3} times, by more than {RATIO_Z} standard errors), less than \
             the {POINT_SAMPLE_RATIO} that decides",
            held / mean,
            held_all / mean_all
        ))
    })
}

/// What [`point_sampled`] found of a logged voltage.
pub(crate) enum Sampling {
    /// Point samples: the trapezoid fits more than [`POINT_SAMPLE_RATIO`] times better.
    Points(String),
    /// Undecided: the trapezoid fits better than a held voltage's noise can make it
    /// ([`noise_bound`]) but by less than [`POINT_SAMPLE_RATIO`]. Every 10th row of an
    /// independent 5 kHz IPM log of moves (noise-free, 500 Hz): 1.21 times, the dynamic fit
    /// K_e +2.3 % at |z| 4.6 with exit 0 before this case was told apart.
    Unclear(String),
}

/// The most a held voltage's white noise can lower the trapezoid's mean squared residual
/// against the held voltage's: `2/(1 + a cos ω_e h)`, `a = e^{−h r_s/L}` the pole of the
/// fastest current channel at the motor estimates `theta` (model order: `r_s`, the
/// inductances, `k_e`) and `ω_e h` the largest electrical angle a sample turns (the logs'
/// `w_m` times `n_p` and their sample time h \[s\], a quarter turn at most). The pole of the
/// current in the rotating frame is `a e^{−j ω_e h}`, and the mean of two samples keeps
/// `(1 + Re(a e^{−j ω_e h}))/2` of the noise's power there (the module doc with the complex
/// pole): the rotation weakens the noise's correlation between samples, and the trapezoid
/// gains more from it. On an independent 10 kHz servo log with 1 V and 0.03 A of noise the
/// refit gained 1.0101–1.0146 times where `2/(1 + a)` allowed 1.0100 (74 of 100 seeds
/// untrusted for it), and the rotation allows 1.0131 (11 of 100 refitted, 3 at the fit's
/// estimate; none by [`RATIO_Z`] standard errors). [`POINT_SAMPLE_RATIO`] (the bound for any pole and a quarter turn)
/// where the estimates give no pole in (0, 1].
fn noise_bound(theta: &[f64], experiments: &[Experiment], n_p: u32) -> f64 {
    let h = experiments.iter().map(Experiment::h).fold(0.0, f64::max);
    let inductances = theta.get(1..theta.len().saturating_sub(1)).unwrap_or_default();
    let poles: Vec<f64> = inductances.iter().map(|l| (-h * theta[0] / l).exp()).collect();
    let a = poles.iter().copied().fold(1.0, f64::min);
    if poles.is_empty() || !poles.iter().all(|a| a.is_finite() && *a > 0.0 && *a <= 1.0) {
        return POINT_SAMPLE_RATIO;
    }
    let turn = experiments
        .iter()
        .filter_map(|e| {
            let w_m = e.get(W_M)?;
            Some(w_m.values.iter().fold(0.0, |m: f64, w| m.max(w.abs())) * f64::from(n_p) * e.h())
        })
        .fold(0.0, f64::max)
        .min(std::f64::consts::FRAC_PI_2);
    2.0 / (1.0 + a * turn.cos())
}

/// The logs with `ud`, `uq` at sample k replaced by the mean of samples k and k + 1 (the
/// last sample kept: it drives no logged current). `None` when a log lacks them.
fn trapezoid(experiments: &[Experiment]) -> Option<Vec<Experiment>> {
    experiments
        .iter()
        .map(|e| {
            let mut e = e.clone();
            for name in [U_D, U_Q] {
                let c = e.get(name)?;
                let v = &c.values;
                let values: Vec<f64> =
                    (0..v.len()).map(|k| v.get(k + 1).map_or(v[k], |next| 0.5 * (v[k] + next))).collect();
                let unit = c.unit.clone();
                e = e.with_channel(Channel::new(name, unit, values)).ok()?;
            }
            Some(e)
        })
        .collect()
}

/// Batches of the ratio's standard error ([`Squares::ratio_std_error`]).
const RATIO_BATCHES: usize = 32;

/// Per log, per sample, the squared residuals (summed over the outputs) of the held and the
/// trapezoid voltage at one θ \[output unit²\].
struct Squares {
    held: Vec<Vec<f64>>,
    mean: Vec<Vec<f64>>,
}

impl Squares {
    /// The residual sums of squares, held and trapezoid.
    fn sums(&self) -> (f64, f64) {
        let total = |v: &[Vec<f64>]| v.iter().flatten().sum::<f64>();
        (total(&self.held), total(&self.mean))
    }

    /// The standard error of the ratio `R = Σ held/Σ mean` from the spread of
    /// `Σ (held_k − R mean_k)` over [`RATIO_BATCHES`] consecutive batches of samples (batch
    /// means, which the residuals' own correlation leaves consistent: Law & Kelton,
    /// *Simulation Modeling and Analysis*, 3rd ed., 2000, 9.5.3), the delta method's
    /// `√(G/(G − 1) Σ_b B_b²)/Σ mean`; ∞ with fewer than two batches.
    fn ratio_std_error(&self) -> f64 {
        let (held, mean) = self.sums();
        let ratio = held / mean;
        let n: usize = self.held.iter().map(Vec::len).sum();
        let len = n.div_ceil(RATIO_BATCHES).max(1);
        let batches: Vec<f64> = self
            .held
            .iter()
            .zip(&self.mean)
            .flat_map(|(h, m)| h.chunks(len).zip(m.chunks(len)))
            .map(|(h, m)| h.iter().zip(m).map(|(h, m)| h - ratio * m).sum::<f64>())
            .collect();
        let g = batches.len();
        if g < 2 {
            return f64::INFINITY;
        }
        (g as f64 / (g - 1) as f64 * batches.iter().map(|b| b * b).sum::<f64>()).sqrt() / mean
    }
}

/// The squared residuals of `model` at `theta` (its parameters, model order) on the logged
/// `experiments` and on the `trapezoid` logs, each simulated from its measured first
/// current; `None` when a simulation fails.
fn squares_at<M: GreyBoxModel>(
    model: &M,
    experiments: &[Experiment],
    trapezoid: &[Experiment],
    theta: &[f64],
) -> Option<Squares> {
    let squares = |logs: &[Experiment]| -> Option<Vec<Vec<f64>>> {
        logs.iter()
            .map(|e| {
                let prep = Prepared::new(model, e).ok()?;
                let y_hat = simulate(model, &prep, theta, &SimOptions::default()).ok()?;
                let ny = model.n_outputs().max(1);
                let rows = prep.y_rows();
                Some(
                    rows.chunks(ny)
                        .zip(y_hat.chunks(ny))
                        .map(|(y, s)| y.iter().zip(s).map(|(y, s)| (y - s).powi(2)).sum::<f64>())
                        .collect(),
                )
            })
            .collect()
    };
    Some(Squares { held: squares(experiments)?, mean: squares(trapezoid)? })
}

#[cfg(test)]
mod tests {
    use super::Squares;

    /// A ratio that every sample keeps has no sampling error; white squares of one mean
    /// give a ratio of about 1 within a few of its standard errors, and the standard error
    /// shrinks as 1/√n.
    #[test]
    fn the_ratios_standard_error_is_its_batches_spread() {
        let mean: Vec<f64> = (0..4096).map(|k| 1.0 + ((k * 7919) % 97) as f64 / 97.0).collect();
        let exact = Squares { held: vec![mean.iter().map(|m| 2.0 * m).collect()], mean: vec![mean.clone()] };
        assert_eq!(exact.sums(), (2.0 * mean.iter().sum::<f64>(), mean.iter().sum::<f64>()));
        assert!(exact.ratio_std_error().abs() < 1e-15);
        let mut rng = crate::estimate::test_rng::Xorshift::new(17);
        let mut white = |n: usize| (0..n).map(|_| rng.uniform()).collect::<Vec<f64>>();
        let se = |n: usize, white: &mut dyn FnMut(usize) -> Vec<f64>| {
            let s = Squares { held: vec![white(n)], mean: vec![white(n)] };
            let (h, m) = s.sums();
            ((h / m - 1.0) / s.ratio_std_error(), s.ratio_std_error())
        };
        let (z_small, se_small) = se(4096, &mut white);
        let (z_large, se_large) = se(65536, &mut white);
        assert!(z_small.abs() < 3.0 && z_large.abs() < 3.0, "{z_small} {z_large}");
        approx::assert_relative_eq!(se_small / se_large, 4.0, max_relative = 0.35);
        assert!(Squares { held: vec![vec![1.0]], mean: vec![vec![1.0]] }.ratio_std_error().is_infinite());
    }
}
