//! The gains of the adaptation laws (see the parent module's documentation): the thesis'
//! fixed gains, or the normalised ones of [`Adaptation::Normalised`].

use super::super::config::Adaptation;
use super::state::{INFORMATIVE, Mras};
use crate::pmsm::C64;

impl Mras {
    /// The gains `(γ_K, γ_R)` at current `i` (R̂_s adapting when `r_active`) and the mean
    /// information `(P̄_K, P̄_R)` after this sample (unchanged but under
    /// [`Adaptation::Normalised`]).
    pub(super) fn gains(&self, i: C64, r_active: bool) -> (f64, f64, f64, f64) {
        if self.cfg.adaptation != Adaptation::Normalised {
            // −γ_Rs L_s/|i| maps the thesis' gain onto the sensitivity φ_R ≈ −h i/L_s; |i| > 0
            // whenever |i_d| exceeds the threshold.
            let g_r = if r_active { -self.cfg.gamma_rs * self.cfg.l_s / i.norm() } else { 0.0 };
            return (self.cfg.gamma_ke, g_r, self.p_k, self.p_r);
        }
        // P̄ ← P̄ + (h/τ)(|φ|² − P̄), started at the first value; γ = (h/τ)/P̄. A sample with
        // less than INFORMATIVE of the mean information leaves P̄ as it is: without that, P̄
        // decays at standstill (φ_K = 0) and the gain winds up, the classic failure of
        // forgetting without excitation (Ioannou & Sun 1996, 4.11; Fortescue, Kershenbaum &
        // Ydstie, Automatica 17 (1981) 831–835).
        let mean = |p: f64, info: f64, a: f64| match p > 0.0 {
            false => info,
            true if info >= INFORMATIVE * p => p + a * (info - p),
            true => p,
        };
        let gain = |p: f64, a: f64| if p > 0.0 && p.is_finite() { a / p } else { 0.0 };
        let (a_k, a_r) = (self.cfg.h / self.cfg.tau_ke, self.cfg.h / self.cfg.tau_rs);
        let p_k = mean(self.p_k, self.phi_k.norm_sqr(), a_k);
        let p_r = if r_active { mean(self.p_r, self.phi_r.norm_sqr(), a_r) } else { self.p_r };
        (gain(p_k, a_k), if r_active { gain(p_r, a_r) } else { 0.0 }, p_k, p_r)
    }
}
