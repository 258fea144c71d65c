//! The two motors the simulated drive ships with: the default plant of every scenario
//! and of [`DriveConfig::default`](super::DriveConfig), and an interior-magnet one.

use crate::pmsm::{MotorParameters, Saturation, SaturationExponents};

/// A small surface-magnet servo motor (the default plant).
pub const SPM_MOTOR: MotorParameters = MotorParameters { r_s: 1.2, l_d: 5e-3, l_q: 5e-3, psi_f: 0.1, n_p: 4 };
/// A small interior-magnet motor (`L_q > L_d`).
pub const IPM_MOTOR: MotorParameters =
    MotorParameters { r_s: 0.4, l_d: 3e-3, l_q: 7e-3, psi_f: 0.15, n_p: 3 };

/// The magnetics of a saturating interior-magnet motor ([`SATURATED_IPM_MOTOR`]'s plant):
/// the algebraic model (Hinkkanen et al. 2017) with `L_d0 = 3 mH`, `L_q0 = 7 mH`,
/// `ψ_f = 0.15 V s` and exponents `(S, T, U, V) = (4, 2, 1, 0)`; its apparent `L_q` falls
/// from 5.8 mH at no load to 3.7 mH (−36 %) at `i_q = 10 A` (`i_max`), its incremental
/// `L_q` by more than half.
pub const IPM_SATURATION: Saturation = Saturation {
    a_d0: 1.0 / 3e-3,
    a_dd: 6.58e4,
    a_q0: 1.0 / 7e-3,
    a_qq: 7.0e4,
    a_dq: 2.54e4,
    psi_f: 0.15,
    exponents: SaturationExponents { s: 4, t: 2, u: 1, v: 0 },
};

/// What the controller of the saturating IPM assumes: its no-load incremental `L_d`,
/// apparent `L_q` and `ψ_f`, with `R_s = 0.4 Ω`, `n_p = 3` (the plant is [`IPM_SATURATION`]).
pub const SATURATED_IPM_MOTOR: MotorParameters =
    MotorParameters { r_s: 0.4, l_d: 2e-3, l_q: 5.8e-3, psi_f: 0.15, n_p: 3 };
