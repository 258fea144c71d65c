//! The two motors the simulated drive ships with: the default plant of every scenario
//! and of [`DriveConfig::default`](super::DriveConfig), and an interior-magnet one.

use crate::pmsm::MotorParameters;

/// A small surface-magnet servo motor (the default plant).
pub const SPM_MOTOR: MotorParameters = MotorParameters { r_s: 1.2, l_d: 5e-3, l_q: 5e-3, psi_f: 0.1, n_p: 4 };
/// A small interior-magnet motor (`L_q > L_d`).
pub const IPM_MOTOR: MotorParameters =
    MotorParameters { r_s: 0.4, l_d: 3e-3, l_q: 7e-3, psi_f: 0.15, n_p: 3 };
