//! The text report of a mechanical fit ([`MechanicsFit`]): the model with the terms fitted,
//! on the shaft or on a linear axis, the torque (or force) constant, the estimates, the
//! torque model's share of the uncertainty, the covariance used and why, the warnings.

use crate::pmsm::fit::mechanics::MechanicsFit;
use crate::pmsm::fit::report::estimate_table;
use crate::pmsm::model::mechanics::Axis;

impl std::fmt::Display for MechanicsFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let has = |name: &str| self.fit.parameter(name).is_some();
        let estimated = if self.coulomb_speed_estimated { ", ω_c estimated by the lowest loss" } else { "" };
        match self.axis {
            Axis::Rotary => writeln!(
                f,
                "Mechanics (J dω/dt = T_e − B ω − T_c tanh(ω/{:.4e} rad/s{estimated}){}{}{}; K_t {:.6} N m/A; {} \
                 windows of {:.4} s):",
                self.coulomb_speed,
                if has("mgl") { " − m g l sin θ" } else { "" },
                if has("t_0") { " − T_0" } else { "" },
                if self.load_channel { " − T_L (logged)" } else { "" },
                self.k_t,
                self.windows,
                self.window
            )?,
            Axis::Linear { lead } => writeln!(
                f,
                "Mechanics of a linear axis (m dv/dt = F − b v − f_c tanh(v/{:.4e} m/s{}){}{}; force constant \
                 K_f = K_t 2π/lead = {:.6} N/A with K_t {:.6} N m/A and a lead of {lead:.6e} m per revolution; {} \
                 windows of {:.4} s):",
                self.coulomb_speed,
                estimated.replace("ω_c", "v_c"),
                if has("f_0") { " − f_0" } else { "" },
                if self.load_channel { " − F_L (logged)" } else { "" },
                self.k_t * self.axis.radians_per_unit(),
                self.k_t,
                self.windows,
                self.window
            )?,
        }
        write!(f, "{}", estimate_table(&self.fit))?;
        if self.k_t_relative_se > 0.0 {
            let se: Vec<String> = self
                .fit
                .parameters
                .iter()
                .zip(&self.std_errors_with_torque)
                .map(|(p, s)| format!("{} {s:.3e}", p.name))
                .collect();
            writeln!(
                f,
                "the intervals take K_t as exact; with its relative standard error {:.2e} (it scales every \
                 parameter alike) the standard errors are: {}",
                self.k_t_relative_se,
                se.join(", ")
            )?;
        } else {
            writeln!(
                f,
                "the intervals take K_t as exact: its relative error scales every parameter above alike"
            )?;
        }
        let u = &self.fit.uncertainty;
        let q = u.ljung_box.iter().copied().fold(0.0, f64::max);
        match u.method {
            crate::estimate::CovarianceMethod::BatchMeans => writeln!(
                f,
                "intervals from batch means over {} batches of {} windows (the residuals are not white: Ljung–Box \
                 {q:.1} against {:.1})",
                u.batches, u.batch_samples, u.ljung_box_critical
            )?,
            _ => writeln!(
                f,
                "intervals from the white-noise covariance (Ljung–Box {q:.1} against {:.1})",
                u.ljung_box_critical
            )?,
        }
        for w in &self.fit.warnings {
            writeln!(f, "{}{}: {}", if w.untrusted { "untrusted, " } else { "" }, w.code, w.message)?;
        }
        let verdict = if self.fit.trusted() { "trusted" } else { "NOT to be trusted" };
        writeln!(f, "fit {verdict}")
    }
}
