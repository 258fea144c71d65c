//! Which noise an output-error fit's residuals point to: noise on the measured current
//! leaves the simulated current's residual white; noise on the logged voltage (an input of
//! the model) colours it, since the model filters it, while the inverse model's voltage
//! error (`spm::inverse`) holds that noise unfiltered, white. Output error is then biased
//! (errors in variables; Söderström, *Automatica* 43 (2007) 939–958) and the report names
//! the instrumental-variable method, which is not.

use crate::data::Experiment;
use crate::estimate::Warning;
use crate::estimate::metrics;
use crate::estimate::problem::{LagStream, WHITENESS_LAGS};
use crate::model::GreyBoxModel;
use crate::pmsm::log::signals::DqView;
use crate::pmsm::model::interval::C64;
use crate::pmsm::model::setup::PmsmSetup;
use crate::pmsm::model::spm::PmsmSpm;

/// Noise on the logged voltage this small against its RMS value (rounding to a few
/// digits, say) is not worth a word.
pub const NEGLIGIBLE_VOLTAGE_NOISE: f64 = 1e-4;

/// A notice (code `input_noise`) when the inverse model's voltage errors at θ = (r_s, l_s,
/// k_e) of an SPM model driven by the terminal voltage are white in every log and not
/// negligible, for a fit whose own residuals are not white; `None` otherwise, or for a log
/// the inverse model cannot read.
pub(crate) fn input_noise_notice(
    experiments: &[Experiment],
    setup: PmsmSetup,
    theta: &[f64],
) -> Option<Warning> {
    let model = PmsmSpm::from_setup(setup);
    let (mut sse, mut suu, mut n) = (0.0, 0.0, 0usize);
    let mut lags = [Vec::new(), Vec::new()];
    for e in experiments {
        let v = DqView::try_new(e).ok()?;
        let inputs = model.prepare(e).ok()?;
        let c = model.coefficients(theta, &inputs).ok()?;
        let i = |k: usize| C64::new(v.i_d()[k], v.i_q()[k]);
        let mut streams = [LagStream::new(WHITENESS_LAGS), LagStream::new(WHITENESS_LAGS)];
        for k in 0..v.len().saturating_sub(1) {
            let inv = model.inverse_step(&c, &inputs, k);
            let eps = inv.u - inv.voltage(i(k), i(k + 1)).0;
            streams[0].push(&[eps.re]);
            streams[1].push(&[eps.im]);
            sse += eps.norm_sqr();
            suu += inv.u.norm_sqr();
            n += 1;
        }
        for (all, s) in lags.iter_mut().zip(streams) {
            all.push(s.finish());
        }
    }
    let whiteness = lags.map(|l| metrics::whiteness_of(&l));
    let sigma = (sse / (2 * n.max(1)) as f64).sqrt();
    let rms = (suu / (2 * n.max(1)) as f64).sqrt();
    (whiteness.iter().all(|w| w.is_white(n)) && sigma > NEGLIGIBLE_VOLTAGE_NOISE * rms).then(|| {
        Warning::notice(
            "input_noise",
            format!(
                "the current residuals are coloured but the voltage equations' errors are white (σ ≈ {sigma:.3e} V \
                 per axis): noise on the logged voltage, which output error filters into its residuals and which \
                 biases it (errors in variables); --method iv (instrumental variables on the inverse model) is \
                 not biased by it"
            ),
        )
    })
}
