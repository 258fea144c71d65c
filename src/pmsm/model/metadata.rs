//! The metadata every PMSM model shares, as a macro over the motor kind's table.

/// The part of [`crate::model::GreyBoxModel`] every PMSM model shares, from its motor
/// kind's table (`$kind`: a function of the model giving its
/// [`MotorKind`](crate::pmsm::MotorKind)): name, the dq current state and outputs `id`,
/// `iq` \[A\], the channels read (`ud`, `uq`, `w_m`), parameter metadata (`self.params`),
/// advice, and `k_t`, `psi_f` derived with `self.n_p` pole pairs.
macro_rules! pmsm_model_metadata {
    ($kind:expr) => {
        fn name(&self) -> &str {
            ($kind)(self).model_name()
        }
        fn n_states(&self) -> usize {
            2
        }
        fn outputs(&self) -> Vec<$crate::model::Signal> {
            use $crate::pmsm::log::signals::channel;
            vec![$crate::model::Signal::new(channel::I_D, "A"), $crate::model::Signal::new(channel::I_Q, "A")]
        }
        fn input_channels(&self) -> Vec<String> {
            use $crate::pmsm::log::signals::channel;
            [channel::U_D, channel::U_Q, channel::W_M].map(String::from).to_vec()
        }
        fn parameters(&self) -> &[$crate::model::Parameter] {
            &self.params
        }
        fn advice(&self, name: &str) -> Option<String> {
            ($kind)(self).advice(name)
        }
        fn pair_advice(&self, a: &str, b: &str) -> Option<String> {
            ($kind)(self).pair_advice(a, b)
        }
        fn poor_fit_advice(&self) -> Option<String> {
            Some($crate::pmsm::model::kind::POOR_FIT_ADVICE.into())
        }
        fn implausible(&self, theta: &[f64]) -> Vec<String> {
            ($kind)(self).implausible(theta)
        }
        fn derived(&self, theta: &[f64], covariance: &[Vec<f64>]) -> Vec<$crate::model::DerivedEstimate> {
            let se: Vec<f64> = (0..theta.len()).map(|j| covariance[j][j].sqrt()).collect();
            let k = ($kind)(self).parameter_names().len() - 1;
            let corr = covariance.first().and_then(|row| row.get(k)).map_or(0.0, |c| c / (se[0] * se[k]));
            let mut d =
                $crate::pmsm::model::kind::derived(($kind)(self), self.setup.n_p, theta, &se, corr, None);
            let psi = d.iter().find(|q| q.name == "psi_f").map(|q| (q.value, q.std_error));
            if let (Some(t), Some((psi_f, se_psi))) = (&self.setup.thermal, psi) {
                d.extend(t.temperatures(theta[0], se[0], psi_f, se_psi, None));
            }
            d
        }
    };
}
pub(crate) use pmsm_model_metadata;
