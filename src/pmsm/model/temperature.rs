//! Winding and magnet temperatures from the estimates (MODEL.md §3, thesis 3.4): copper
//! `R_s(T) = R_s0 (1 + α (T − T_0))`, NdFeB `ψ_f(T) = ψ_f0 (1 + β (T − T_0))`, solved for T
//! with first-order standard errors `σ_T = σ_R / (α R_s0)`, `σ_T = σ_ψ / (|β| ψ_f0)`.

use crate::error::{Error, Result};
use crate::model::DerivedEstimate;
use serde::{Deserialize, Serialize};

/// Temperature coefficient of copper resistance α \[1/K\].
pub const ALPHA_COPPER: f64 = 0.00393;
/// Temperature coefficient of NdFeB remanence β \[1/K\] (−0.11 %/K).
pub const BETA_NDFEB: f64 = -0.0011;

/// The reference point of the temperature estimates: resistance and flux at `t0`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThermalReference {
    /// Reference temperature T_0 \[°C\].
    pub t0: f64,
    /// Winding resistance at T_0 \[Ω\], if known.
    pub r_s0: Option<f64>,
    /// Magnet flux at T_0 \[V s\], if known.
    pub psi_f0: Option<f64>,
    /// Copper coefficient α \[1/K\].
    pub alpha: f64,
    /// Magnet coefficient β \[1/K\].
    pub beta: f64,
}

impl ThermalReference {
    /// Copper and NdFeB at `t0` \[°C\] with the resistance `r_s0` \[Ω\] and the flux `psi_f0`
    /// \[V s\] there (either may be unknown).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] (option `thermal`) for a non-finite T_0 or a reference value
    /// that is not positive and finite.
    pub fn try_new(t0: f64, r_s0: Option<f64>, psi_f0: Option<f64>) -> Result<Self> {
        let bad = |reason: String| Error::InvalidOption { option: "thermal".into(), reason };
        if !t0.is_finite() {
            return Err(bad(format!("reference temperature {t0} °C is not finite")));
        }
        for (name, v) in [("r_s0", r_s0), ("psi_f0", psi_f0)] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(bad(format!("{name} = {v} must be positive and finite")));
            }
        }
        Ok(Self { t0, r_s0, psi_f0, alpha: ALPHA_COPPER, beta: BETA_NDFEB })
    }

    /// `t_winding` and `t_magnet` \[°C\] from the resistance `r_s` ± `se_r` \[Ω\] and the flux
    /// `psi_f` ± `se_psi` \[V s\], for the reference values that are known. With the 95 %
    /// intervals of `r_s` and `psi_f` (`ci`: `[r_s's, psi_f's]`, their units), each
    /// temperature, a linear function of one of them, takes its interval through that
    /// function ([`DerivedEstimate::ci95`]; ends swapped for a negative coefficient, β < 0);
    /// without, the fit sets `± t·std_error`.
    pub fn temperatures(
        &self,
        r_s: f64,
        se_r: f64,
        psi_f: f64,
        se_psi: f64,
        ci: Option<[[f64; 2]; 2]>,
    ) -> Vec<DerivedEstimate> {
        let make = |name: &str, f: &dyn Fn(f64) -> f64, value: f64, std_error: f64, ci: Option<[f64; 2]>| {
            // Ordered, a NaN end kept (min/max would drop it).
            let ends = ci.map(|[lo, hi]| {
                let (a, b) = (f(lo), f(hi));
                if a <= b { [a, b] } else { [b, a] }
            });
            DerivedEstimate {
                name: name.into(),
                unit: "degC".into(),
                value: f(value),
                std_error,
                ci95: ends,
                experiment: None,
            }
        };
        let mut out = Vec::new();
        if let Some(r0) = self.r_s0 {
            let f = |r: f64| self.t0 + (r / r0 - 1.0) / self.alpha;
            out.push(make("t_winding", &f, r_s, se_r / (self.alpha * r0).abs(), ci.map(|c| c[0])));
        }
        if let Some(p0) = self.psi_f0 {
            let f = |p: f64| self.t0 + (p / p0 - 1.0) / self.beta;
            out.push(make("t_magnet", &f, psi_f, se_psi / (self.beta * p0).abs(), ci.map(|c| c[1])));
        }
        out
    }
}
