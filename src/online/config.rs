//! Configuration of the MRAS observer (thesis 5.1, MODEL.md §7).

use crate::error::{Error, Result};
use crate::pmsm::VoltageHold;
use serde::{Deserialize, Serialize};

/// How the `K_e` adaptation law scales with speed (thesis 5.1.1 and 5.1.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Adaptation {
    /// `dK̂_e/dt = γ_Ke Dᵀ e`, `D = [0, −√(2/3) ω_m/L_s]ᵀ`: the gain grows with the
    /// mechanical speed ω_m (thesis eq. 5.3, design by Lyapunov theory).
    #[default]
    Lyapunov,
    /// `ω_m` in the adaptation's `D` replaced by `sign(ω_m)` (+1 at ω_m = 0): a gain that
    /// does not depend on the speed's size; needs a larger `γ_Ke` (thesis 5.1.2).
    Relay,
    /// The Lyapunov directions with gains normalised by the information each parameter
    /// receives: `γ = (h/τ) / P̄`, `P̄` the mean of `|φ|²` (the squared sensitivity of the
    /// prediction to the parameter) over the last τ (`MrasConfig::tau_ke`, `tau_rs`). Each
    /// estimate then settles with the time constant τ whatever the motor's size and speed,
    /// and averages the noise over it: the normalised LMS / recursive least squares with
    /// forgetting factor `1 − h/τ` (Haykin, *Adaptive Filter Theory*, 5th ed., 2014, 6.1
    /// and 10.2; Ioannou & Sun, *Robust Adaptive Control*, 1996, 4.5.5 on normalisation).
    /// No motor-specific gain.
    Normalised,
}

/// Settings of [`super::Mras`]; plain data with serde and thesis defaults.
///
/// The known quantities (`n_p`, `l_s`, `h`) have no meaningful default: `Default` leaves
/// them at 0, which [`MrasConfig::validate`] rejects until they are set. Defaults of the
/// observer gains are the thesis' Exp 1 values (thesis 5.1.1, MODEL.md §7):
/// `f = 100 1/s`, `γ_Ke = 0.001`, `γ_Rs = −10`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MrasConfig {
    /// Pole pairs n_p (`ω_e = n_p ω_m`), at least 1.
    pub n_p: u32,
    /// Known stator inductance L_s \[H\], positive; the d-axis inductance `L_d` when
    /// [`MrasConfig::l_q`] is given.
    pub l_s: f64,
    /// Known q-axis inductance `L_q` \[H\] of a salient (interior-magnet) machine, positive;
    /// `None` (the default, and what a configuration without the field parses to) for
    /// surface magnets, `L_d = L_q = l_s`. With `Some(l_q)`, `l_q ≠ l_s`, the observer steps
    /// the salient model ([`greybox_observer::Ipm`], the augmented exponential of
    /// [`crate::pmsm::ExactPlant`]; see [`super::Mras`]); `Some(l_s)` is
    /// the surface-magnet observer.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub l_q: Option<f64>,
    /// Sample time h \[s\], positive; [`super::track()`] takes it from the log.
    pub h: f64,
    /// Observer feedback gain f \[1/s\] per axis, `F = diag(f, f)`, at least 0 (thesis 100).
    pub f: f64,
    /// Adaptation gain γ_Ke of `K_e`, at least 0 (thesis 0.001; units such that
    /// `dK̂_e/dt = γ_Ke Dᵀ e` is in V s/rad per s). With [`Adaptation::Relay`] use a larger one.
    /// The gain is motor specific: at a steady operating point `K̂_e` converges at the rate
    /// `γ_Ke emf² σ / (L_s² |σ + jω_e|²)` \[1/s\], `emf = √(2/3) ω_m`, `σ = R_s/L_s + f`
    /// (quasi-static error of the observer), so a small `L_s` needs a much smaller `γ_Ke`
    /// (salient: about the same with `L_q` in place of `L_s`; e.g. 10⁻⁵ for
    /// gym-electric-motor's `L_q = 1.3 mH` where motulator's 7.5 mH takes the default).
    pub gamma_ke: f64,
    /// Adaptation gain γ_Rs \[Ω/(A s)\] of `R_s`, at most 0: thesis sign convention
    /// `dR̂_s/dt = γ_Rs e_d` with `e = x − x̂` and `i_d > 0` (thesis eq. 5.4, γ_Rs = −10).
    pub gamma_rs: f64,
    /// Speed scaling of the `K_e` law, or the normalised laws.
    pub adaptation: Adaptation,
    /// Time constant τ_Ke \[s\] of the `K_e` estimate under [`Adaptation::Normalised`],
    /// positive (default 0.5 s).
    pub tau_ke: f64,
    /// Time constant τ_Rs \[s\] of the `R_s` estimate under [`Adaptation::Normalised`]
    /// (counted over the samples where it adapts), positive (default 0.5 s).
    pub tau_rs: f64,
    /// `R_s` adapts only while `|i_d|` exceeds this \[A\] (d-current injection, thesis
    /// 5.1.1); at least 0. Default 0.5 A (our choice; the thesis names none).
    pub i_d_threshold: f64,
    /// Initial estimate of K_e \[V s/rad\], finite.
    pub k_e0: f64,
    /// Initial estimate of R_s \[Ω\], at least 0.
    pub r_s0: f64,
    /// How the voltage is held over a period (MODEL.md §4); the observer's step is exact
    /// for this hold.
    pub hold: VoltageHold,
}

impl Default for MrasConfig {
    fn default() -> Self {
        // The observer crate's defaults (one table for the library and the C ABI).
        let s = greybox_observer::Settings::<f64>::new(0, 0.0, 0.0);
        Self {
            n_p: s.n_p,
            l_s: s.l_s,
            l_q: None,
            h: s.h,
            f: s.f,
            gamma_ke: s.gamma_ke,
            gamma_rs: s.gamma_rs,
            adaptation: Adaptation::Lyapunov,
            tau_ke: s.tau_ke,
            tau_rs: s.tau_rs,
            i_d_threshold: s.i_d_threshold,
            k_e0: s.k_e0,
            r_s0: s.r_s0,
            hold: VoltageHold::Stator,
        }
    }
}

impl MrasConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming the first bad field: `n_p` = 0, `l_s`, `l_q` (when
    /// given) or `h` not positive and finite, `f`, `gamma_ke`, `i_d_threshold` or `r_s0` negative or not
    /// finite, `gamma_rs` positive (the thesis' sign: it must be ≤ 0) or not finite,
    /// `k_e0` not finite.
    pub fn validate(&self) -> Result<()> {
        let bad = |option: &str, reason: String| Err(Error::InvalidOption { option: option.into(), reason });
        if self.n_p == 0 {
            return bad("n_p", "the number of pole pairs must be at least 1".into());
        }
        for (name, v) in [
            ("l_s", self.l_s),
            ("l_q", self.l_q.unwrap_or(1.0)),
            ("h", self.h),
            ("tau_ke", self.tau_ke),
            ("tau_rs", self.tau_rs),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, format!("must be positive and finite, got {v}"));
            }
        }
        for (name, v) in [
            ("f", self.f),
            ("gamma_ke", self.gamma_ke),
            ("i_d_threshold", self.i_d_threshold),
            ("r_s0", self.r_s0),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, format!("must be finite and at least 0, got {v}"));
            }
        }
        if !(self.gamma_rs.is_finite() && self.gamma_rs <= 0.0) {
            return bad(
                "gamma_rs",
                format!(
                    "must be finite and at most 0 (thesis convention dR_s/dt = gamma_rs e_d, e = x − x̂), got {}",
                    self.gamma_rs
                ),
            );
        }
        if !self.k_e0.is_finite() {
            return bad("k_e0", format!("must be finite, got {}", self.k_e0));
        }
        Ok(())
    }

    /// Whether the observer steps the salient model: `l_q` given and different from `l_s`.
    pub fn salient(&self) -> bool {
        self.l_q.is_some_and(|l_q| l_q != self.l_s)
    }

    /// Whether `R_s` adapts at a d-current `i_d` \[A\]: `|i_d| > i_d_threshold` and
    /// `γ_Rs ≠ 0` (thesis 5.1.1: without d current the d equation carries no information
    /// on `R_s`). False for a non-finite `i_d`.
    pub fn r_s_adapts(&self, i_d: f64) -> bool {
        i_d.abs() > self.i_d_threshold && (self.gamma_rs != 0.0 || self.adaptation == Adaptation::Normalised)
    }
}
