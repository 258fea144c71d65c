//! The start of a fit through the switching-resolved PWM inverter: the motor's parameters
//! and the averaged dead-time voltage `v_dt` from the linear least-squares regression with
//! the averaged inverter model (thesis 5.2.1; MODEL.md §4), `v_dt` split into the dead time
//! and the device threshold (`V_dt ≈ t_d f_sw U_dc + u_th`), and the carrier's first edge,
//! when not given, as the one whose one-step prediction at that start fits the logs better.

use crate::data::Experiment;
use crate::error::Result;
use crate::model::GreyBoxModel;
use crate::pmsm::linear::start::least_squares_start;
use crate::pmsm::log::signals::{DqView, channel};
use crate::pmsm::log::{DqLogs, peak_current};
use crate::pmsm::model::inverter::InverterModel;
use crate::pmsm::model::pwm::{CarrierEdge, PmsmPwm, PwmInverter};
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::options::PmsmFitOptions;

/// The start in model order (motor, then the inverter's) and a note saying where it came
/// from.
///
/// # Errors
/// Those of the least-squares start; [`Error::InvalidOption`] for a log without a sample
/// time the carrier allows, or without the DC-link voltage.
pub(crate) fn start(
    dq: &DqLogs<'_>,
    options: &PmsmFitOptions,
    pwm: &PwmInverter,
) -> Result<(Vec<f64>, String)> {
    let averaged = InverterModel::default();
    let (names, theta) = least_squares_start(
        dq.views(),
        options.pole_pairs,
        options.model,
        options.input,
        options.cable_resistance + pwm.r_on,
        Some(&averaged),
    )?;
    let m = options.model.parameter_names().len();
    let v_dt = names.iter().position(|n| n == "v_dt").map_or(1.0, |j| theta[j]);
    let e = &dq.experiments()[0];
    let f_sw = pwm.carrier(e.h())?;
    let u_dc = pwm.u_dc_samples(e)?;
    let u_dc = u_dc.iter().sum::<f64>() / u_dc.len().max(1) as f64;
    let nuisance = pwm.start(v_dt, f_sw, u_dc);
    let note = format!(
        "PWM inverter start from the averaged least-squares regression: v_dt = {v_dt:.4} V at {f_sw:.0} Hz and \
         U_dc = {u_dc:.1} V, split as t_d = {:.4e} s, u_th = {:.4} V (V_dt ≈ t_d f_sw U_dc + u_th)",
        nuisance[0], nuisance[1]
    );
    Ok((theta[..m].iter().copied().chain(nuisance).collect(), note))
}

/// Samples of each log the first-edge choice predicts.
const EDGE_SAMPLES: usize = 20_000;

/// `pwm` with its first carrier edge chosen when not given: each edge's one-step prediction
/// from the measured current at `theta`, the lower sum of squares; with a note.
///
/// # Errors
/// Those of the model's `prepare` and `coefficients`.
pub(crate) fn resolve_edge(
    experiments: &[Experiment],
    setup: PmsmSetup,
    options: &PmsmFitOptions,
    pwm: PwmInverter,
    theta: &[f64],
) -> Result<(PwmInverter, Option<String>)> {
    if pwm.first_edge.is_some() {
        return Ok((pwm, None));
    }
    let loss = |edge: CarrierEdge| -> Result<f64> {
        let model = PmsmPwm::new(setup, options.model, PwmInverter { first_edge: Some(edge), ..pwm });
        let mut sum = 0.0;
        for e in experiments {
            let inputs = model.prepare(e)?;
            let c = model.coefficients(theta, &inputs)?;
            let (i_d, i_q) = (e.channel(channel::I_D)?, e.channel(channel::I_Q)?);
            let start = options.input.unknown_start();
            for k in start..(e.len() - 1).min(start + EDGE_SAMPLES) {
                let mut x = [0.0; 2];
                model.step(&c, &inputs, k, &[i_d[k], i_q[k]], &mut x);
                sum += (x[0] - i_d[k + 1]).powi(2) + (x[1] - i_q[k + 1]).powi(2);
            }
        }
        Ok(sum)
    };
    let (rising, falling) = (loss(CarrierEdge::Rising)?, loss(CarrierEdge::Falling)?);
    let edge = if falling < rising { CarrierEdge::Falling } else { CarrierEdge::Rising };
    let note = format!(
        "PWM carrier: the first period {} (one-step loss at the start {rising:.4e} rising, {falling:.4e} falling)",
        match edge {
            CarrierEdge::Rising => "rising",
            CarrierEdge::Falling => "falling",
        }
    );
    Ok((PwmInverter { first_edge: Some(edge), ..pwm }, Some(note)))
}

/// Widths of the smooth leg state of the continuation, relative to the logs' largest
/// current: each stage's fit starts from the previous one's estimate.
pub(crate) const CONTINUATION_WIDTHS: [f64; 3] = [0.02, 0.005, 0.001];

/// The fits that lead to a PWM model whose leg state is the sign or an estimated width:
/// the same inverter at the fixed widths [`CONTINUATION_WIDTHS`] × the largest current, with
/// their parameter names (`names` without `i_w`); none for a known width.
pub(crate) fn continuation<'a>(
    views: &[DqView<'_>],
    pwm: &PwmInverter,
    names: &[&'a str],
) -> Vec<(PwmInverter, Vec<&'a str>)> {
    if pwm.i_w.is_some() {
        return Vec::new();
    }
    let peak = peak_current(views);
    let stage_names: Vec<&'a str> = names.iter().copied().filter(|n| *n != "i_w").collect();
    CONTINUATION_WIDTHS
        .iter()
        .map(|w| {
            let stage = PwmInverter { i_w: Some((w * peak).max(1e-9)), estimate_i_w: false, ..*pwm };
            (stage, stage_names.clone())
        })
        .collect()
}

/// The start of a stage (parameters `stage_names`): the previous stage's estimate, or the
/// model's start `theta` (parameters `names`) for the first.
pub(crate) fn carried(
    prev: Option<&crate::estimate::FitResult>,
    stage_names: &[&str],
    theta: &[f64],
    names: &[&str],
) -> Vec<f64> {
    stage_names
        .iter()
        .map(|n| match prev.and_then(|p| p.parameter(n)) {
            Some(p) => p.value,
            None => names.iter().position(|m| m == n).map_or(f64::NAN, |j| theta[j]),
        })
        .collect()
}

/// The final fit's start (parameters `names`) from the last stage's estimate: an estimated
/// width starts at the last stage's; with a note.
pub(crate) fn from_continuation(
    last: &crate::estimate::FitResult,
    width: Option<f64>,
    names: &[&str],
    pwm: &PwmInverter,
    theta: &[f64],
) -> (Vec<f64>, String) {
    let mut start = carried(Some(last), names, theta, names);
    if let (Some(j), Some(w)) = (names.iter().position(|n| *n == "i_w"), width) {
        // The stages hold the width fixed: the estimate starts at the last one.
        start[j] = w;
    }
    let note = format!(
        "PWM inverter: the fit follows a continuation of the leg state (2/π) atan(i/i_w) over widths {} of the \
         largest current (loss at the last {:.6e}), then {}",
        CONTINUATION_WIDTHS.map(|w| format!("{w}")).join(", "),
        last.fit.loss,
        if pwm.estimate_i_w { "i_w estimated" } else { "the sign" }
    );
    (start, note)
}

/// Samples at a log's start a PWM fit weights out beyond the reference's delay: the carrier's
/// state before the log (the legs' last commands, a blanking carried over) is unknown, so
/// the first periods' switching is not the model's.
pub(crate) const UNKNOWN_CARRIER_SAMPLES: usize = 2;

/// The samples at a log's start a PWM fit weights out with the voltage `input`: the
/// reference's delay, the sample it acts on and [`UNKNOWN_CARRIER_SAMPLES`].
pub(crate) fn skipped(input: crate::pmsm::model::interval::VoltageInput) -> usize {
    crate::pmsm::checks::limit::delay_of(input) + 1 + UNKNOWN_CARRIER_SAMPLES
}

/// A weighting that weights out the first `skip` samples of every log.
#[derive(Debug)]
pub(crate) struct SkipStart<'a> {
    pub inner: &'a dyn crate::estimate::Weighting,
    pub skip: usize,
}

impl crate::estimate::Weighting for SkipStart<'_> {
    fn name(&self) -> String {
        format!(
            "{} without the first {} samples (the carrier's state before the log)",
            self.inner.name(),
            self.skip
        )
    }
    fn sample_weight(&self, e: &Experiment, k: usize) -> f64 {
        if k < self.skip { 0.0 } else { self.inner.sample_weight(e, k) }
    }
    fn output_weights(&self) -> Option<Vec<f64>> {
        self.inner.output_weights()
    }
    fn check(&self, e: &Experiment) -> Result<()> {
        self.inner.check(e)
    }
}

/// Share of each log the leading stages fit: one part in `LEADING_SHARE`.
pub(crate) const LEADING_SHARE: usize = 4;

/// Most pieces a log's leading share is cut into (spread along the log, so that they see
/// its operating points).
pub(crate) const LEADING_PIECES: usize = 8;

/// Fewest samples of a leading piece; a log whose share holds fewer than two such pieces
/// is fitted whole.
pub(crate) const LEADING_PIECE_SAMPLES: usize = 2048;

/// The logs of the stages that lead to the final fits (the continuation over smooth leg
/// states and the loop's first search): of each log, up to
/// [`LEADING_PIECES`] pieces of [`LEADING_PIECE_SAMPLES`] samples or more, spread evenly
/// from its first sample to its last and holding one [`LEADING_SHARE`]th of it, each named
/// `NAME~k`; `None` when no log is long enough to cut (the stages then fit the logs).
///
/// Why this is the same problem on fewer samples: the one-step predictor restarts each
/// period from the measured current (the default gain 1), so a period's prediction depends
/// on its own samples alone, and a piece is a set of periods (it starts at an even sample,
/// which keeps the carrier's edge of a double-update log; its first periods are weighted
/// out as a log's are). These stages only lead into the loss's basin; the unmasked fit, the
/// mask, the masked fits and the loop's second search at the final estimate take every
/// sample.
///
/// # Errors
/// Those of [`Experiment::slice`] (none for the ranges made here).
pub(crate) fn leading_logs(experiments: &[Experiment]) -> Result<Option<Vec<Experiment>>> {
    let pieces_of = |n: usize| (n / LEADING_SHARE / LEADING_PIECE_SAMPLES).min(LEADING_PIECES);
    if experiments.iter().all(|e| pieces_of(e.len()) < 2) {
        return Ok(None);
    }
    let mut logs = Vec::new();
    for e in experiments {
        let (n, pieces) = (e.len(), pieces_of(e.len()));
        if pieces < 2 {
            logs.push(e.clone());
            continue;
        }
        let len = (n / LEADING_SHARE / pieces) & !1;
        for k in 0..pieces {
            let first = (k * (n - len) / (pieces - 1)) & !1;
            logs.push(e.slice(first..first + len)?.renamed(format!("{}~{}", e.name(), k + 1)));
        }
    }
    Ok(Some(logs))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Channel;

    /// A log of `n` samples whose one channel holds the sample index.
    fn log(n: usize) -> Experiment {
        let k = Channel::new("k", "1", (0..n).map(|k| k as f64).collect());
        Experiment::try_new("log", 1e-4, vec![k]).unwrap()
    }

    #[test]
    fn the_leading_share_is_spread_over_the_log_in_even_pieces() {
        let n = 72_001;
        let pieces = leading_logs(&[log(n)]).unwrap().expect("a long log is cut");
        assert_eq!(pieces.len(), LEADING_PIECES);
        let starts: Vec<usize> = pieces.iter().map(|p| p.channel("k").unwrap()[0] as usize).collect();
        let len = pieces[0].len();
        assert!(len >= LEADING_PIECE_SAMPLES && len.is_multiple_of(2), "{len}");
        let held: usize = pieces.iter().map(Experiment::len).sum();
        assert!(held <= n / LEADING_SHARE && held + 2 * LEADING_PIECES >= n / LEADING_SHARE, "{held}");
        assert_eq!(starts[0], 0);
        assert!(starts.iter().all(|s| s.is_multiple_of(2)), "{starts:?}");
        assert!(starts.windows(2).all(|w| w[1] >= w[0] + len), "{starts:?}");
        assert!(starts[LEADING_PIECES - 1] + len + 2 >= n, "{starts:?}");
        assert_eq!(pieces[2].name(), "log~3");
        // Each piece holds its own consecutive samples.
        let k = pieces[3].channel("k").unwrap();
        assert!(k.windows(2).all(|w| w[1] == w[0] + 1.0));
        assert!((pieces[3].t0() - starts[3] as f64 * 1e-4).abs() < 1e-12);
    }

    #[test]
    fn a_log_too_short_to_cut_is_fitted_whole() {
        let short = LEADING_SHARE * 2 * LEADING_PIECE_SAMPLES - 1;
        assert!(leading_logs(&[log(short)]).unwrap().is_none());
        // Beside a long log, the short one is taken whole.
        let logs =
            leading_logs(&[log(short), log(LEADING_SHARE * 2 * LEADING_PIECE_SAMPLES)]).unwrap().unwrap();
        assert_eq!(logs.len(), 3);
        assert_eq!(logs[0].len(), short);
        assert_eq!(logs[1].len(), LEADING_PIECE_SAMPLES);
    }
}
