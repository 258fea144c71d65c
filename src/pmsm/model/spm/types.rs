//! The surface-magnet model's types: its data, its θ-dependent coefficients and the model
//! itself ([`PmsmSpm`] documents the step).

use crate::model::Parameter;
use crate::pmsm::model::interval::{C64, IntervalSource, VoltageHold};
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::model::setup::PmsmSetup;

/// The motor kind of the model.
pub(super) const KIND: MotorKind = MotorKind::Spm;

/// The data of the SPM step, independent of θ: its intervals' source (the experiment's
/// speed and voltage channels, shared, not copied), from which each interval's terms are
/// formed as the pass needs them ([`IntervalSource::interval`]), and the inverter's error
/// directions.
#[derive(Clone, Debug)]
pub struct SpmInputs {
    /// Sample time, pole pairs, speed and voltage of the intervals.
    pub source: IntervalSource,
    /// The inverter's voltage error per unit `v_dt` of each interval, length N − 1, in the
    /// convention of the voltage term (rotated to the period's end for the stator hold);
    /// empty without the inverter model.
    pub dt: Vec<C64>,
}

/// θ-dependent coefficients of the SPM step.
#[derive(Clone, Debug)]
pub struct SpmCoefficients {
    /// Number of parameters n_θ (3, or 4 with `v_dt`).
    pub(super) nth: usize,
    /// Inverter voltage error `v_dt` \[V\] (0 without the inverter model).
    pub(super) v_dt: f64,
    pub(super) r: f64,
    pub(super) l: f64,
    pub(super) k_e: f64,
    /// `e^{−R_s h/L_s}`.
    pub(super) d: f64,
    /// `1 − e^{−R_s h/L_s}` without cancellation.
    pub(super) one_minus_d: f64,
    /// `(1 − e^{−R_s h/L_s})/R_s` \[1/Ω\].
    pub(super) g: f64,
    pub(super) g_r: f64,
    pub(super) g_l: f64,
    /// `∂a/∂R_s / a = −h/L_s`.
    pub(super) a_r: f64,
    /// `∂a/∂L_s / a = R_s h/L_s²`.
    pub(super) a_l: f64,
}

/// Surface-magnet PMSM (`L_d = L_q = L_s`) with the exact zero-order-hold step.
///
/// State and output `x = y = (i_d, i_q)` \[A, peak\]; parameters `θ = (r_s, l_s, k_e)`
/// \[Ω, H, V s/rad\]. Continuous model (thesis eq. 5.1, MODEL.md §2), in complex form with
/// `i = i_d + j i_q`, `ω_e = n_p ω_m`:
///
/// ```text
/// L_s di/dt = u − (R_s + j ω_e L_s) i − j √(2/3) K_e ω_m
/// ```
///
/// Exact step over one period (MODEL.md §4), `z = R_s + j ω_e L_s`, `a = e^{−z h/L_s}`:
///
/// ```text
/// dq hold:      i[k+1] = a i[k] + (1 − a)/z · (u[k] − j e)
/// stator hold:  i[k+1] = a i[k] + u₀ e^{−jφ} (1 − e^{−R_s h/L_s})/R_s − (1 − a)/z · j e
/// ```
///
/// with `e = √(2/3) K_e ω_m`, `φ = ω_e h`, `u₀ = u[k] jφ/(1 − e^{−jφ})`; `ω_m` is the
/// interval mean `(ω_m[k] + ω_m[k+1])/2`. The rotation `e^{−jφ}` and `u₀` depend on the
/// data only; they are formed block by block in the pass from the experiment's own
/// channels, which [`GreyBoxModel::prepare`](crate::model::GreyBoxModel::prepare) shares
/// rather than copies (one sine and cosine of `φ/2` an interval, so that a fit of the terminal voltage keeps nothing per sample
/// beyond the data; a reference input keeps its start-of-period voltages, the inverter
/// model its error directions, 16 bytes an interval each).
/// `e^{−R_s h/L_s}` depends on θ only and is computed once per θ. Sensitivities
/// differentiate this recursion (forward sensitivity), so one pass gives residuals and
/// gradients.
///
/// Surface-magnet PMSM model with exact sampled-data step and analytic sensitivities.
///
/// Parameters `(r_s [Ω], l_s [H], k_e [V s/rad])`; `r_s` and `l_s` bounded positive,
/// `k_e` unbounded (a negative estimate means the log's sign convention differs).
/// Source: thesis eq. 5.1 and section 5.2 (Tenerz 2011); MODEL.md §2, §4.
#[derive(Clone, Debug)]
pub struct PmsmSpm {
    pub(super) setup: PmsmSetup,
    pub(super) params: Vec<Parameter>,
}

impl PmsmSpm {
    /// SPM model of a machine with `n_p` pole pairs (`ω_e = n_p ω_m`), the given voltage
    /// hold and default parameter metadata, driven by the terminal voltage. `n_p = 0` is
    /// reported by [`GreyBoxModel::prepare`](crate::model::GreyBoxModel::prepare) as
    /// [`PmsmError::InvalidPolePairs`](crate::pmsm::PmsmError::InvalidPolePairs).
    pub fn new(n_p: u32, hold: VoltageHold) -> Self {
        Self::from_setup(PmsmSetup::new(n_p, hold))
    }

    crate::pmsm::model::setup::pmsm_model_setup!();
}
