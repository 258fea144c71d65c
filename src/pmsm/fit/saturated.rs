//! The saturated IPM fit of drive logs: the linear IPM fit first (its parameters start the
//! saturated model and stand beside it in the report, so the load-dependent bias of the
//! linear inductances shows), then the prediction-error fit of [`PmsmSaturated`].

use crate::data::Experiment;
use crate::error::{Error, Result};
use crate::estimate::{FitResult, fit};
use crate::pmsm::fit::flux_map::inductance_table;
use crate::pmsm::fit::report::PmsmFit;
use crate::pmsm::fit::report::estimate_table;
use crate::pmsm::fit::workflow::fit_pmsm;
use crate::pmsm::model::interval::SQRT_2_3;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::saturated::{PmsmSaturated, saturated_substeps};
use crate::pmsm::model::saturation::{Inductances, Saturation, SaturationExponents};
use crate::pmsm::options::PmsmFitOptions;
use serde::{Deserialize, Serialize};

/// A saturated fit: the linear IPM fit it started from, the saturated fit, the fitted
/// magnetics and the inductances at the logs' operating points.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SaturatedFit {
    /// The magnetically linear IPM fit of the same logs (`r_s, l_d, l_q, k_e`).
    pub linear: FitResult,
    /// The saturated fit (`r_s, a_d0, a_dd, a_q0, a_qq, a_dq, psi_f`).
    pub fit: FitResult,
    /// The fitted magnetics.
    pub model: Saturation,
    /// RK4 substeps per period.
    pub substeps: usize,
    /// Apparent and incremental inductances at zero current, at the logs' largest `|i_q|`
    /// (`i_d = 0`, half and full) and at their most negative `i_d` with the largest `|i_q|`.
    pub operating_points: Vec<Inductances>,
}

/// Fits the saturated IPM model ([`PmsmSaturated`], exponents `exponents`) to drive logs
/// read by [`read_log`](crate::pmsm::read_log), after the linear IPM fit
/// ([`fit_pmsm`] with `options`, its model forced to IPM) that gives its start: `a_d0 =
/// 1/L_d`, `a_q0 = 1/L_q`, `ψ_f` from `K_e`, and saturation coefficients that lower the
/// inverse inductances by 10 % at the largest flux the logs reach.
///
/// # Errors
/// Those of [`fit_pmsm`] and [`fit`]; [`Error::InvalidOption`] (`model`) when the linear
/// fit gives a non-positive inductance or `K_e` (no usable start).
pub fn fit_saturated(
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    exponents: SaturationExponents,
) -> Result<SaturatedFit> {
    let options = PmsmFitOptions { model: MotorKind::Ipm, ..options.clone() };
    let linear: PmsmFit = fit_pmsm(experiments, &options)?;
    let value = |name: &str| linear.report.parameter(name).map_or(f64::NAN, |p| p.value);
    let (r_s, l_d, l_q, k_e) = (value("r_s"), value("l_d"), value("l_q"), value("k_e"));
    let n_p = options.pole_pairs;
    let psi_f = k_e * SQRT_2_3 / f64::from(n_p);
    if !(l_d > 0.0 && l_q > 0.0 && psi_f > 0.0 && r_s > 0.0) {
        return Err(Error::InvalidOption {
            option: "model".into(),
            reason: format!(
                "the linear IPM fit (r_s {r_s:.4e}, l_d {l_d:.4e}, l_q {l_q:.4e}, k_e {k_e:.4e}) gives no start \
                 for the saturated model: check the log's setup with `greybox fit` first"
            ),
        });
    }
    let (mut i_max, mut i_q_max, mut i_d_min, mut w_max) = (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    for e in experiments {
        let (i_d, i_q, w) = (e.channel("id")?, e.channel("iq")?, e.channel("w_m")?);
        for k in 0..e.len() {
            i_max = i_max.max(i_d[k].hypot(i_q[k]));
            i_q_max = i_q_max.max(i_q[k].abs());
            i_d_min = i_d_min.min(i_d[k]);
            w_max = w_max.max(w[k].abs());
        }
    }
    let e = exponents;
    let psi_q = (l_q * i_q_max).max(1e-3 * psi_f);
    let pw = |x: f64, n: u32| x.powi(n as i32);
    let start_model = Saturation {
        a_d0: 1.0 / l_d,
        a_dd: 0.1 / l_d / pw(psi_f, e.s),
        a_q0: 1.0 / l_q,
        a_qq: 0.1 / l_q / pw(psi_q, e.t),
        a_dq: 0.1 / l_q * f64::from(e.u + 2) / (pw(psi_f, e.u + 2) * pw(psi_q, e.v)),
        psi_f,
        exponents: e,
    };
    let theta = start_model.theta();
    let start = [r_s, theta[0], theta[1], theta[2], theta[3], theta[4], theta[5]];
    let h = experiments.first().map_or(1.0, Experiment::h);
    let substeps = saturated_substeps(&start_model, r_s, 1.5 * i_max, f64::from(n_p) * w_max, h)?;
    let model = PmsmSaturated::new(n_p, e, substeps, &start);
    // Two starts: the guess above, and the linear model itself (saturation coefficients 0),
    // which the saturated model nests. A minimum above the linear fit's residual is a local
    // one; the second start then runs, and the lower of the two is kept.
    let mut result = fit(&model, experiments, &start, &options.pem)?;
    if !below_linear(&result, &linear.report) {
        let linear_start = [r_s, theta[0], 0.0, theta[2], 0.0, 0.0, theta[5]];
        if let Ok(second) = fit(&model, experiments, &linear_start, &options.pem)
            && mean_square(&second) < mean_square(&result)
        {
            result = second;
        }
    }
    let values: Vec<f64> = result.parameters.iter().map(|p| p.value).collect();
    let magnetics = model.magnetics(&values);
    let operating_points = [[0.0, 0.0], [0.0, 0.5 * i_q_max], [0.0, i_q_max], [i_d_min, i_q_max]]
        .into_iter()
        .map(|i| magnetics.inductances(i))
        .collect::<Result<Vec<_>>>()?;
    Ok(SaturatedFit { linear: linear.report, fit: result, model: magnetics, substeps, operating_points })
}

/// The mean of the outputs' squared rms residuals \[A²\].
fn mean_square(r: &FitResult) -> f64 {
    let rms = &r.fit.rms_residual;
    rms.iter().map(|x| x * x).sum::<f64>() / rms.len().max(1) as f64
}

/// Relative excess of the saturated fit's mean-square residual over the linear fit's above
/// which the saturated fit (which nests the linear model) is a local minimum: 1 %.
pub const LOCAL_MINIMUM_EXCESS: f64 = 0.01;

/// Whether `saturated` fits at least as well as `linear` (within [`LOCAL_MINIMUM_EXCESS`]).
fn below_linear(saturated: &FitResult, linear: &FitResult) -> bool {
    mean_square(saturated) <= (1.0 + LOCAL_MINIMUM_EXCESS) * mean_square(linear)
}

impl SaturatedFit {
    /// Whether the saturated fit is to be trusted: its own gate passed
    /// ([`FitResult::trusted`]) and its residual is no larger than the linear fit's (which
    /// it nests; a larger one is a local minimum).
    pub fn trusted(&self) -> bool {
        self.fit.trusted() && below_linear(&self.fit, &self.linear)
    }

    /// Why the fit is not to be trusted: the gate's warning codes, `local_minimum`; empty
    /// when trusted.
    pub fn untrusted_reasons(&self) -> Vec<String> {
        let mut out = self.fit.untrusted_codes();
        if !below_linear(&self.fit, &self.linear) {
            out.push("local_minimum".into());
        }
        out
    }
}

impl std::fmt::Display for SaturatedFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let e = self.model.exponents;
        writeln!(f, "Magnetically linear IPM fit (the start):")?;
        write!(f, "{}", estimate_table(&self.linear))?;
        writeln!(
            f,
            "\nSaturated IPM fit (Hinkkanen et al. 2017, exponents S = {}, T = {}, U = {}, V = {}; RK4, {} substeps per period):",
            e.s, e.t, e.u, e.v, self.substeps
        )?;
        write!(f, "{}", estimate_table(&self.fit))?;
        let rms = |r: &FitResult| {
            r.fit.rms_residual.iter().map(|x| format!("{x:.4e}")).collect::<Vec<_>>().join(", ")
        };
        writeln!(
            f,
            "\nrms current residual [A] (i_d, i_q): linear {}; saturated {}",
            rms(&self.linear),
            rms(&self.fit)
        )?;
        let verdict = if self.fit.solver.success { "converged" } else { "did NOT converge" };
        writeln!(f, "saturated fit {verdict}: {} iterations", self.fit.solver.iterations)?;
        if !below_linear(&self.fit, &self.linear) {
            writeln!(
                f,
                "the saturated fit's residual exceeds the linear fit's, which it contains: a local minimum, not to be \
                 trusted (try other exponents)"
            )?;
        }
        let zero: Vec<&str> =
            self.fit.parameters.iter().filter(|p| p.at_bound).map(|p| p.name.as_str()).collect();
        if !zero.is_empty() {
            writeln!(
                f,
                "{} at zero: the logs show no saturation of that kind (or too little current to see it); where all \
                 are, the linear fit describes the logs",
                zero.join(", ")
            )?;
        }
        f.write_str(&inductance_table(&self.operating_points))
    }
}
