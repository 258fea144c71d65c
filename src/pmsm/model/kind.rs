//! The motor kinds and their parameter table: the single source of truth for parameter
//! names, units, bounds, what excites each parameter, and the quantities derived from them.
//!
//! Advice after MODEL.md §6 (thesis 5.1.1, 6.3): `K_e` needs speed, `R_s` current at low
//! speed or a d-current injection, `L` current transients or `i_d ≠ 0` at speed. Derived
//! quantities after MODEL.md §2: `K_t = √(3/2) K_e` \[N m/A\], `ψ_f = √(2/3) K_e / n_p` \[V s\].

use crate::estimate::{ParameterEstimate, interval_quantile};
use crate::model::DerivedEstimate;
use crate::model::Parameter;
use serde::{Deserialize, Serialize};

/// Which machine a model or regression assumes.
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum MotorKind {
    /// Surface magnets, `θ = (r_s, l_s, k_e)`.
    #[default]
    Spm,
    /// Interior magnets, `θ = (r_s, l_d, l_q, k_e)`.
    Ipm,
}

/// One row of a motor kind's parameter table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParameterInfo {
    /// Symbol, e.g. `r_s`.
    pub name: &'static str,
    /// SI unit, e.g. `ohm` (K_e per mechanical rad/s).
    pub unit: &'static str,
    /// Bounded to positive values (the resistance and inductances; `k_e` is unbounded: a
    /// negative estimate means the log's sign convention differs).
    pub positive: bool,
    /// What data determine it, for the advice when it is poorly determined.
    pub excited_by: &'static str,
}

const R_S: ParameterInfo = ParameterInfo {
    name: "r_s",
    unit: "ohm",
    positive: true,
    excited_by: "add low-speed data with current, or a d-current injection",
};
const K_E: ParameterInfo =
    ParameterInfo { name: "k_e", unit: "V s/rad", positive: false, excited_by: "add data at higher speed" };
const L_EXCITED: &str = "add current transients (steps of the current reference) or i_d ≠ 0 at speed";
const L_S: ParameterInfo = ParameterInfo { name: "l_s", unit: "H", positive: true, excited_by: L_EXCITED };
const L_D: ParameterInfo = ParameterInfo { name: "l_d", unit: "H", positive: true, excited_by: L_EXCITED };
const L_Q: ParameterInfo = ParameterInfo { name: "l_q", unit: "H", positive: true, excited_by: L_EXCITED };
const SPM: [ParameterInfo; 3] = [R_S, L_S, K_E];
const IPM: [ParameterInfo; 4] = [R_S, L_D, L_Q, K_E];
const SPM_NAMES: [&str; 3] = ["r_s", "l_s", "k_e"];
const IPM_NAMES: [&str; 4] = ["r_s", "l_d", "l_q", "k_e"];
const SPM_UNITS: [&str; 3] = ["ohm", "H", "V s/rad"];
const IPM_UNITS: [&str; 4] = ["ohm", "H", "H", "V s/rad"];

/// Advice for a strongly correlated pair, sorted by name.
const PAIRS: [(&str, &str, &str); 4] = [
    ("k_e", "r_s", "add low-speed data with current, where R_s acts without back-EMF"),
    ("l_s", "r_s", "add current steps of both signs and several levels"),
    ("l_d", "r_s", "add current steps of both signs and several levels"),
    ("l_q", "r_s", "add current steps of both signs and several levels"),
];

/// The smallest inductance estimate of a PMSM fit \[H\]: `l_s`, or the smaller of `l_d`
/// and `l_q`; ∞ when the fit has none (the electrical time constant `L/R` and the
/// dead-time mask's threshold take the fastest axis).
pub(crate) fn smallest_inductance(fit: &crate::estimate::FitResult) -> f64 {
    ["l_s", "l_d", "l_q"]
        .iter()
        .filter_map(|n| fit.parameter(n).map(|p| p.value))
        .fold(f64::INFINITY, f64::min)
}

/// What to check when a PMSM fit is poor.
pub const POOR_FIT_ADVICE: &str = "check the pole pairs, the units and frames of the columns, the voltage hold, and \
                                   that all logs come from one motor; with the reference voltage, the speed estimate \
                                   behind the modulator's advance (--speed-pll estimate) and the inverter's dead time \
                                   (--dead-time estimate)";

impl MotorKind {
    /// The parameter table, model order.
    pub fn table(self) -> &'static [ParameterInfo] {
        match self {
            Self::Spm => &SPM,
            Self::Ipm => &IPM,
        }
    }
    /// Parameter names in order.
    pub fn parameter_names(self) -> &'static [&'static str] {
        match self {
            Self::Spm => &SPM_NAMES,
            Self::Ipm => &IPM_NAMES,
        }
    }
    /// Parameter units in order (`Ω`, `H`, `V s/rad`; K_e per mechanical rad/s).
    pub fn parameter_units(self) -> &'static [&'static str] {
        match self {
            Self::Spm => &SPM_UNITS,
            Self::Ipm => &IPM_UNITS,
        }
    }
    /// Model name in reports: `pmsm_spm` or `pmsm_ipm`.
    pub fn model_name(self) -> &'static str {
        match self {
            Self::Spm => "pmsm_spm",
            Self::Ipm => "pmsm_ipm",
        }
    }
    /// Default parameter metadata: positive parameters bounded below by 1e-12, the scale
    /// taken from the start value.
    pub fn parameters(self) -> Vec<Parameter> {
        self.table()
            .iter()
            .map(|p| Parameter {
                name: p.name.into(),
                unit: p.unit.into(),
                nominal: None,
                lower: if p.positive { 1e-12 } else { f64::NEG_INFINITY },
                upper: f64::INFINITY,
                fixed: false,
                nuisance: false,
            })
            .collect()
    }
    /// The non-physical values of θ (model order; entries beyond the table, such as an
    /// inverter's, are not looked at): a resistance, inductance or back-EMF constant that
    /// is not positive. A negative `k_e` fits a log whose speed has the other sign than the
    /// back-EMF (a flipped speed column, d and q swapped, another angle convention).
    pub fn implausible(self, theta: &[f64]) -> Vec<String> {
        self.table()
            .iter()
            .zip(theta)
            .filter(|(_, v)| v.is_nan() || **v <= 0.0)
            .map(|(p, v)| {
                let why = if p.name == "k_e" {
                    "the back-EMF has the other sign than the speed: a speed column of the wrong sign, d and q \
                     swapped, or voltage and current swapped; check the columns before fitting again"
                } else {
                    "a motor's resistance and inductances are positive: check the columns and their units"
                };
                format!("{} = {v:.4e} {} is not positive: {why}", p.name, p.unit)
            })
            .collect()
    }
    /// The entries of `parameters` (named as the table, `name[log]` per log) whose 95 %
    /// interval reaches a value [`implausible`](Self::implausible) finds while the estimate
    /// is physical, each as `name ∈ [lo, hi] unit (advice)`: the trust gate's `undetermined`
    /// ([`crate::estimate::gate`]) for the estimators that form their own intervals (the
    /// steady-state equations, instrumental variables). Fixed and nuisance parameters,
    /// parameters at a bound and intervals that are not finite are left out.
    pub(crate) fn undetermined(self, parameters: &[ParameterEstimate]) -> Vec<String> {
        let at = |name: &str, value: f64| !self.implausible_entry(name, value).is_empty();
        parameters
            .iter()
            .filter(|q| !(q.fixed || q.nuisance || q.at_bound) && q.ci95.iter().all(|c| c.is_finite()))
            .filter(|q| !at(&q.name, q.value) && q.ci95.iter().any(|&end| at(&q.name, end)))
            .map(|q| crate::estimate::gate::undetermined_entry(q, self.advice(&q.name)))
            .collect()
    }
    /// [`implausible`](Self::implausible) of the entry `name` (the table's, `name[log]` per
    /// log) at `value`, the other entries at a physical 1; none for a name the table lacks
    /// (a nuisance term such as the steady-state equations' control period).
    pub(crate) fn implausible_entry(self, name: &str, value: f64) -> Vec<String> {
        let base = name.split('[').next().unwrap_or(name);
        let Some(k) = self.table().iter().position(|p| p.name == base) else { return Vec::new() };
        let mut theta = vec![1.0; self.table().len()];
        theta[k] = value;
        self.implausible(&theta)
    }
    /// Advice for a poorly determined parameter `name` (with or without `[experiment]`).
    pub fn advice(self, name: &str) -> Option<String> {
        let base = name.split('[').next().unwrap_or(name);
        if base == "v_dt" {
            return Some(format!(
                "{name} poorly determined: add current reversals at several current levels and low speed, where \
                 the dead-time voltage is a large part of the voltage"
            ));
        }
        let p = self.table().iter().find(|p| p.name == base)?;
        Some(format!("{name} poorly determined: {}", p.excited_by))
    }
    /// Advice for two strongly correlated parameters.
    pub fn pair_advice(self, a: &str, b: &str) -> Option<String> {
        let base = |n: &str| n.split('[').next().unwrap_or(n).to_string();
        let mut pair = [base(a), base(b)];
        pair.sort_unstable();
        PAIRS.iter().find(|(x, y, _)| pair[0] == *x && pair[1] == *y).map(|(_, _, t)| t.to_string())
    }
}

/// The quantities derived from θ (model order of `kind`) on a machine with `n_p` pole
/// pairs, with their standard errors (first-order propagation; `corr_rk` is the
/// correlation of the `r_s` and `k_e` estimates, 0 when unknown):
/// - `k_t` \[N m/A\]: torque per ampere of peak phase current, `√(3/2) K_e` (MODEL.md §2);
/// - `psi_f` \[V s\]: `√(2/3) K_e / n_p`;
/// - `k_t_rms` \[N m/A\]: torque per ampere of RMS phase current, `√2 k_t = √3 K_e` (the
///   datasheet convention);
/// - `k_v` \[rpm/V\]: mechanical rpm per volt of peak line-to-line back-EMF,
///   `60/(2π √2 K_e)` (the hobby/ODrive/VESC convention: `k_t = 8.27/k_v`, 8.27 =
///   `(60/2π)(√3/2)`);
/// - `k_m` \[N m/√W\]: the motor constant, torque per square root of copper loss,
///   `k_t/√(1.5 R_s) = K_e/√R_s` (copper loss `3 R_s I_rms² = 1.5 R_s |i_dq|²`).
///
/// With the parameters' 95 % intervals `ci` (θ order, the parameters' units), each quantity
/// of `K_e` alone takes `K_e`'s interval through its function (increasing for `k_t`,
/// `psi_f`, `k_t_rms`, decreasing for `k_v`, whose interval needs `K_e`'s to exclude 0), so
/// that an asymmetric interval stays the same statement; `k_m`, of two parameters, is
/// `± q·std_error` with q the heavier of its parameters' quantiles (the longer side of each
/// interval over its standard error: an interval widened with fewer degrees of freedom
/// widens `k_m`'s alike). Without `ci` every quantity leaves [`DerivedEstimate::ci95`] to
/// the fit (`± t·std_error`).
pub fn derived(
    kind: MotorKind,
    n_p: u32,
    theta: &[f64],
    std_error: &[f64],
    corr_rk: f64,
    ci: Option<&[[f64; 2]]>,
) -> Vec<DerivedEstimate> {
    let Some(j) = kind.parameter_names().iter().position(|n| *n == "k_e") else { return Vec::new() };
    let (Some(&k_e), Some(&se)) = (theta.get(j), std_error.get(j)) else { return Vec::new() };
    let k_e_ci = ci.and_then(|c| c.get(j)).copied();
    let make = |name: &str, unit: &str, value: f64, std_error: f64, ci95: Option<[f64; 2]>| DerivedEstimate {
        name: name.into(),
        unit: unit.into(),
        value,
        std_error,
        ci95,
        experiment: None,
    };
    // A multiple `a K_e` (a > 0) takes K_e's interval times a.
    let scaled = |a: f64| k_e_ci.map(|[lo, hi]| [a * lo, a * hi]);
    let kt = 1.5f64.sqrt();
    let psi = (2.0f64 / 3.0).sqrt() / f64::from(n_p.max(1));
    let k_v = 60.0 / (2.0 * std::f64::consts::PI * std::f64::consts::SQRT_2 * k_e);
    let per_volt = 60.0 / (2.0 * std::f64::consts::PI * std::f64::consts::SQRT_2);
    // k_v = c/K_e decreases in K_e: the interval's ends swap, where K_e's excludes 0.
    let k_v_ci = k_e_ci.filter(|[lo, hi]| lo * hi > 0.0).map(|[lo, hi]| [per_volt / hi, per_volt / lo]);
    let mut out = vec![
        make("k_t", "N m/A", kt * k_e, kt * se, scaled(kt)),
        make("psi_f", "V s", psi * k_e, psi * se, scaled(psi)),
        make("k_t_rms", "N m/A", 3f64.sqrt() * k_e, 3f64.sqrt() * se, scaled(3f64.sqrt())),
        make("k_v", "rpm/V", k_v, (k_v * se / k_e).abs(), k_v_ci),
    ];
    if let (Some(&r), Some(&se_r)) = (theta.first(), std_error.first()) {
        // k_m = K_e/√R: ∂/∂K_e = 1/√R, ∂/∂R = −K_e/(2 R^{3/2}).
        let (a, b) = (1.0 / r.sqrt(), -k_e / (2.0 * r.powf(1.5)));
        let c = if corr_rk.is_finite() { corr_rk } else { 0.0 };
        let var = a * a * se * se + b * b * se_r * se_r + 2.0 * a * b * c * se * se_r;
        let (k_m, se_m) = (k_e / r.sqrt(), var.max(0.0).sqrt());
        // The heavier quantile of r_s's and K_e's intervals (their longer side over their
        // standard error), where both are given and finite.
        let quantile = |j: usize, v: f64, s: f64| {
            ci.and_then(|c| c.get(j)).map(|c| interval_quantile(*c, v, s)).filter(|q| q.is_finite())
        };
        let q = quantile(0, r, se_r).zip(quantile(j, k_e, se)).map(|(a, b)| a.max(b));
        out.push(make("k_m", "N m/sqrt(W)", k_m, se_m, q.map(|q| [k_m - q * se_m, k_m + q * se_m])));
    }
    out
}
