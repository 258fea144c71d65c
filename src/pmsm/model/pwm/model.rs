//! [`PmsmPwm`]: the SPM or IPM current equations driven through the switching-resolved
//! inverter, as a [`GreyBoxModel`] with exact sensitivities.

use super::dual::{Dual, N, Scalar};
use super::modulator::{Carrier, duty_ratios, halves};
use super::period::{self, Params, Period};
use super::{CarrierEdge, PwmInverter, PwmUpdate};
use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::model::{GreyBoxModel, Parameter, Sensitivities};
use crate::pmsm::log::signals::{DqView, channel, check_pole_pairs};
use crate::pmsm::model::interval::{VoltageInput, controller_frame, reference_channels};
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;

/// The data of the PWM-resolved step, independent of θ: per interval the angle, speeds,
/// DC link and the carrier's plan (about 200 bytes an interval).
#[derive(Clone, Debug)]
pub struct PwmInputs {
    pub(super) periods: Vec<Period>,
    /// The measured dq current at each sample \[A\], for the predictor's correction (the
    /// experiment's channels, shared, not copied).
    pub(super) i_d: crate::data::Values,
    pub(super) i_q: crate::data::Values,
}

/// How far one period of the one-step predictor is from a switching decision the data
/// cannot tell ([`PmsmPwm::sign_margins`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignMargin {
    /// The residual's norm `|y[k] − x̂[k]|` \[A\].
    pub residual: f64,
    /// The smallest phase-current magnitude at a piece's start, where a leg state takes
    /// that current's sign \[A\], in the period started from the previous period's
    /// prediction `x̂[k]` rather than from the measured `y[k]`: a choice of samples by this
    /// margin then does not depend on the noise of the measurement the period restarts from
    /// (a choice by `y[k]` keeps a period near the margin when that noise pushes its current
    /// away from zero, which biased `u_th` by +6 … +65 % and `t_d` by −6 … 0 % on the shared
    /// 3 µs log with 0.05 A of noise per phase; from `x̂[k]`: −22 … +17 % and −2 … +2 %).
    pub current: f64,
    /// The smallest duty ratio's distance to 0 or 1 \[1\] (0 for a clamped leg).
    pub duty: f64,
}

/// θ-dependent coefficients: the parameters in the step's order.
#[derive(Clone, Copy, Debug)]
pub struct PwmCoefficients {
    pub(super) q: Params<f64>,
    /// θ itself, padded: the values the sensitivity pass seeds its dual numbers with.
    pub(super) theta: [f64; N],
    /// The predictor's gain k_o.
    pub(super) k_o: f64,
    /// Number of parameters n_θ.
    pub(super) nth: usize,
}

/// A surface- or interior-magnet PMSM (`θ = (r_s, l_s, k_e)` or `(r_s, l_d, l_q, k_e)`,
/// then `t_d` \[s\], `u_th` \[V\], and, when estimated, `i_w` \[A\] and the predictor gain
/// `k_o`; [`PwmInverter::parameter_names`])
/// whose voltage is the controller's reference through a switching-resolved PWM inverter.
/// State and output: the predicted dq current `x̂[k]` \[A, peak\].
///
/// From each period's reference (after the delay and angle advance of
/// [`VoltageInput::Reference`]) the modulator's duty ratios (min-max zero sequence or sine),
/// the carrier comparison's switching instants (double or single update), the dead time
/// that blanks each leg after its switching instant with the leg following the direction
/// of its phase current as the model predicts it at that instant, the threshold `u_th` of
/// the conducting device; between those instants the phase voltages are constant and each
/// piece is an exact step of the current equations (the rotating particular solution and
/// the 2×2 exponential; MODEL.md §2, §4; Moler & Van Loan 2003). Sensitivities are exact
/// by forward-mode differentiation, including those through the switching instants.
///
/// The step is a one-step predictor in innovation form (Ljung, *System Identification*,
/// 2nd ed., 4.3 and 7.2): `x̂[k+1] = f(x̂[k] + k_o (y[k] − x̂[k]))`, with `y` the measured
/// current. With `k_o = 1` it restarts every period from the measurement (equation error),
/// with 0 it simulates (output error). Neither alone suits a PWM log: a simulation's current
/// drifts from the measured one and, near a zero crossing, the dead time's sign then
/// follows the drift, while a restart from a noisy measurement takes the noise as the
/// state. The gain is 1 by default ([`PwmInverter::predictor_gain`]), or estimated with the
/// other parameters, as the prediction error method does for a Kalman predictor's gain.
///
/// The reference is transformed to the stator frame with the logged angle and advanced
/// with the logged speed, or, with a phase-locked loop in the input
/// ([`VoltageInput::Reference`]'s `speed_pll`), with that loop's angle and speed: a
/// sensored controller's frame (`controller_frame` in the interval module; unlike the
/// averaged model's loop, which advances with the loop's speed only).
///
/// Reads `id`, `iq`, `w_m`, `theta_m`, `ud_ref`, `uq_ref` (and `u_dc` unless the inverter
/// gives it).
#[derive(Clone, Debug)]
pub struct PmsmPwm {
    setup: PmsmSetup,
    kind: MotorKind,
    inverter: PwmInverter,
    params: Vec<Parameter>,
}

impl PmsmPwm {
    /// The model of `kind` for `setup` (its input must be the reference voltage) through
    /// `inverter`, with default parameter metadata.
    pub fn new(setup: PmsmSetup, kind: MotorKind, inverter: PwmInverter) -> Self {
        let mut params = kind.parameters();
        params.extend(inverter.parameters());
        Self { setup, kind, inverter, params }
    }
    /// The inverter.
    pub fn inverter(&self) -> &PwmInverter {
        &self.inverter
    }
    /// The setup (pole pairs, input, cable, thermal reference).
    pub fn setup(&self) -> &PmsmSetup {
        &self.setup
    }
    /// Mutable parameter metadata (bounds, fixed flags, nominal values).
    pub fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }

    /// The one-step predictor at `theta` over a prepared log (N samples) from its measured
    /// first current: per sample k its [`SignMargin`] (the period before it, its current
    /// margin from the prediction; at k = 0 a residual of 0 and infinite margins).
    ///
    /// # Errors
    /// Those of [`coefficients`](GreyBoxModel::coefficients) (θ of the wrong length, an
    /// invalid θ).
    pub fn sign_margins(&self, theta: &[f64], inputs: &PwmInputs) -> Result<Vec<SignMargin>> {
        self.predict(theta, inputs, true)
    }

    /// The one-step predictor's residual norms `|y[k] − x̂[k]|` \[A\] at `theta` over a
    /// prepared log (N samples; 0 at k = 0): [`sign_margins`](Self::sign_margins)' residuals
    /// without the margins, at half its cost (one step a period, not two).
    ///
    /// # Errors
    /// As [`sign_margins`](Self::sign_margins).
    pub fn one_step_residuals(&self, theta: &[f64], inputs: &PwmInputs) -> Result<Vec<f64>> {
        Ok(self.predict(theta, inputs, false)?.into_iter().map(|m| m.residual).collect())
    }

    /// The predictor of [`sign_margins`](Self::sign_margins), the current margins stepped
    /// only when `margins` (infinite otherwise).
    fn predict(&self, theta: &[f64], inputs: &PwmInputs, margins: bool) -> Result<Vec<SignMargin>> {
        use rayon::prelude::*;
        let c = self.coefficients(theta, inputs)?;
        let (n, periods) = (inputs.periods.len(), &inputs.periods);
        let measured = |k: usize| [inputs.i_d[k], inputs.i_q[k]];
        let mut out = vec![SignMargin { residual: 0.0, current: f64::INFINITY, duty: f64::INFINITY }; n + 1];
        // A restarting predictor's prediction at k is the step from the measurement at
        // k − 1 alone: the log is cut into parts stepped in parallel, each started by that
        // one step; any other gain carries the prediction from the log's start.
        let part = if self.restarts() { 2048 } else { n.max(1) };
        out[1..].par_chunks_mut(part).enumerate().for_each(|(i, chunk)| {
            let k0 = i * part;
            let mut x = match k0 {
                0 => measured(0),
                _ => period::step_nearest(&c.q, &periods[k0 - 1], measured(k0 - 1)).0,
            };
            for (j, o) in chunk.iter_mut().enumerate() {
                let (k, per) = (k0 + j, &periods[k0 + j]);
                let (next, _) = period::step_nearest(&c.q, per, self.start_of(c.k_o, x, measured(k)));
                let current = if margins { period::step_nearest(&c.q, per, x).1 } else { f64::INFINITY };
                x = next;
                let residual = (inputs.i_d[k + 1] - x[0]).hypot(inputs.i_q[k + 1] - x[1]);
                *o = SignMargin { residual, current, duty: per.duty_margin };
            }
        });
        Ok(out)
    }

    /// The step's parameters in scalar `T` from θ, `make(value, index)` forming each.
    pub(super) fn params<T: Scalar>(&self, theta: &[f64], make: impl Fn(f64, usize) -> T) -> Params<T> {
        let m = self.kind.parameter_names().len();
        let r = make(theta[0] + self.setup.cable_resistance + self.inverter.r_on, 0);
        let (l_d, l_q, k_e) = match self.kind {
            MotorKind::Spm => (make(theta[1], 1), make(theta[1], 1), make(theta[2], 2)),
            MotorKind::Ipm => (make(theta[1], 1), make(theta[2], 2), make(theta[3], 3)),
        };
        let i_w = if self.inverter.estimate_i_w {
            Some(make(theta[m + 2], m + 2))
        } else {
            self.inverter.i_w.filter(|w| *w > 0.0).map(T::cst)
        };
        Params { r, l_d, l_q, k_e, t_d: make(theta[m], m), u_th: make(theta[m + 1], m + 1), i_w }
    }

    /// Whether the predictor restarts every period from the measured current (the gain
    /// `k_o` held at 1): then a period's step depends on that current only, not on the
    /// prediction before it, and the periods are independent of each other.
    pub(crate) fn restarts(&self) -> bool {
        self.inverter.predictor_gain == Some(1.0)
    }

    /// The period's start `x̂ + k_o (y − x̂)` from the prediction `x` and the measured `y`
    /// \[A\]; exactly `y` when the predictor [`restarts`](Self::restarts) (the sum would
    /// round it by the prediction's last bits).
    #[inline]
    pub(crate) fn start_of(&self, k_o: f64, x: [f64; 2], y: [f64; 2]) -> [f64; 2] {
        if self.restarts() { y } else { [x[0] + k_o * (y[0] - x[0]), x[1] + k_o * (y[1] - x[1])] }
    }
}

impl GreyBoxModel for PmsmPwm {
    type Inputs = PwmInputs;
    type Coefficients = PwmCoefficients;

    crate::pmsm::model::metadata::pmsm_model_metadata!(|m: &Self| m.kind);

    fn prepare(&self, e: &Experiment) -> Result<PwmInputs> {
        check_pole_pairs(self.setup.n_p)?;
        let VoltageInput::Reference { delay, advance, speed_pll } = self.setup.input else {
            return Err(Error::InvalidOption {
                option: "inverter".into(),
                reason: "the PWM inverter model is driven by the voltage reference (--voltage reference)"
                    .into(),
            });
        };
        let v = DqView::try_new(e)?;
        let (h, np) = (v.h(), f64::from(self.setup.n_p));
        self.inverter.carrier(h)?;
        let theta_m = e.channel(channel::THETA_M)?;
        let (ud, uq, w_adv) = reference_channels(&v, self.setup.n_p, delay, advance, None)?;
        let u_dc = self.inverter.u_dc_samples(e)?;
        // The controller's frame: the logged angle and the advance speed, or a sensored
        // drive's angle estimate that tracks the encoder through a phase-locked loop.
        let frame = speed_pll.map(|alpha| controller_frame(theta_m, v.w_m(), self.setup.n_p, h, alpha));
        let rising0 = self.inverter.first_edge != Some(CarrierEdge::Falling);
        let mut carrier = Carrier::default();
        let w_m = v.w_m();
        // The mean speed inside each period from the angle (`angle_speed`).
        let i_q = e.values(channel::I_Q)?;
        let mean = super::angle_speed::MeanSpeed::fit(theta_m, w_m, i_q, h);
        let periods = (0..v.len() - 1)
            .map(|k| {
                let j = k.saturating_sub(delay);
                let angle = match &frame {
                    Some((theta_c, w_c)) => theta_c[j] + advance * w_c[j] * h,
                    None => np * theta_m[j] + advance * w_adv[j] * h,
                };
                let (s, c) = angle.sin_cos();
                let (alpha, beta) = (c * ud[j] - s * uq[j], s * ud[j] + c * uq[j]);
                let d = duty_ratios(&self.inverter, alpha, beta, u_dc[j]);
                let rising = match self.inverter.update {
                    PwmUpdate::Double => k.is_multiple_of(2) == rising0,
                    PwmUpdate::Single => rising0,
                };
                // The rotor's acceleration over the period (`acceleration`).
                let a_m = (w_m[k + 1] - w_m[k]) / h;
                let w = mean.mean(&w_m[k..k + 2], &i_q[k..k + 2], h);
                Period::new(
                    np * theta_m[k],
                    np * w,
                    w,
                    u_dc[k],
                    halves(&self.inverter, &mut carrier, d, rising, h),
                )
                .accelerating(np * a_m, a_m)
            })
            .collect();
        Ok(PwmInputs { periods, i_d: e.values(channel::I_D)?.clone(), i_q: i_q.clone() })
    }

    fn coefficients(&self, theta: &[f64], _inputs: &PwmInputs) -> Result<PwmCoefficients> {
        let nth = self.params.len();
        if theta.len() != nth {
            return Err(Error::InvalidOption {
                option: "theta".into(),
                reason: format!("{} values for the {nth} parameters of `{}`", theta.len(), self.name()),
            });
        }
        let q: Params<f64> = self.params(theta, |v, _| v);
        self.setup.series_resistance(theta[0])?;
        crate::pmsm::model::interval::check_positive("l_d", q.l_d)?;
        crate::pmsm::model::interval::check_positive("l_q", q.l_q)?;
        crate::pmsm::model::interval::check_finite("k_e", q.k_e)?;
        for (name, v) in self.params.iter().zip(theta).skip(self.kind.parameter_names().len()) {
            if !(v.is_finite() && *v >= 0.0) {
                return Err(Error::InvalidParameter {
                    name: name.name.clone(),
                    value: *v,
                    reason: "an inverter parameter is finite and not negative".into(),
                });
            }
        }
        let k_o = self.inverter.predictor_gain.unwrap_or(theta[nth - 1]);
        let theta = std::array::from_fn(|j| theta.get(j).copied().unwrap_or(0.0));
        Ok(PwmCoefficients { q, theta, k_o, nth })
    }

    #[inline]
    fn step(&self, c: &PwmCoefficients, inp: &PwmInputs, k: usize, x: &[f64], x_next: &mut [f64]) {
        let y = [inp.i_d[k], inp.i_q[k]];
        let [d, q] = period::step(&c.q, &inp.periods[k], self.start_of(c.k_o, [x[0], x[1]], y));
        x_next[0] = d;
        x_next[1] = q;
    }

    fn sensitivities(&self) -> Option<&dyn Sensitivities<PwmInputs, PwmCoefficients>> {
        (self.params.len() <= N).then_some(self as _)
    }

    fn block_kernel(&self) -> Option<&dyn crate::model::BlockKernel<PwmInputs, PwmCoefficients>> {
        (self.restarts() && self.params.len() <= N).then_some(self as _)
    }
}

impl Sensitivities<PwmInputs, PwmCoefficients> for PmsmPwm {
    fn step_sensitivity(
        &self,
        c: &PwmCoefficients,
        inp: &PwmInputs,
        k: usize,
        x: &[f64],
        s: &[f64],
        x_next: &mut [f64],
        s_next: &mut [f64],
    ) {
        let m = c.nth;
        let q: Params<Dual> = self.params(&c.theta, Dual::seed);
        let row = |i: usize| std::array::from_fn(|j| if j < m { s[i * m + j] } else { 0.0 });
        let k_o = match self.inverter.predictor_gain {
            Some(g) => Dual::cst(g),
            None => Dual::seed(c.k_o, m - 1),
        };
        let y = [inp.i_d[k], inp.i_q[k]];
        let x0 = if self.restarts() {
            y.map(Dual::cst)
        } else {
            let x0 = [Dual::new(x[0], row(0)), Dual::new(x[1], row(1))];
            [x0[0] + k_o * (Dual::cst(y[0]) - x0[0]), x0[1] + k_o * (Dual::cst(y[1]) - x0[1])]
        };
        let xn = period::step_dual(&q, &inp.periods[k], x0);
        for (i, v) in xn.iter().enumerate() {
            x_next[i] = v.v;
            s_next[i * m..(i + 1) * m].copy_from_slice(&v.d[..m]);
        }
    }

    fn output_sensitivity(
        &self,
        _c: &PwmCoefficients,
        _inp: &PwmInputs,
        _k: usize,
        _x: &[f64],
        s: &[f64],
        dy: &mut [f64],
    ) {
        let n = dy.len();
        dy.copy_from_slice(&s[..n]);
    }
}
