//! Tests of the period's step, and the test helpers other modules' tests use: a period
//! and the step's parameters as dual-number constants.

use super::super::PwmInverter;
use super::super::dual::Dual;
use super::super::modulator::{Carrier, halves};
use super::*;

/// At `t_d = 0` (its bound) the step's derivative over `t_d` is the one from above, not
/// 0: a difference quotient over 1 ns agrees to 1e-3 of its size, hard and smooth legs
/// (before, the instants of length-0 pieces were merged and the derivative was 0).
#[test]
fn the_derivative_over_t_d_holds_at_zero() {
    let per = test_period();
    for i_w in [None, Some(0.5)] {
        let q = Params { r: 0.35, l_d: 3.2e-3, l_q: 7.5e-3, k_e: 0.42, t_d: 0.0, u_th: 1.2, i_w };
        let at = |t_d: f64| step(&Params { t_d, ..q }, &per, [-0.2, 0.1]);
        let dual = step(
            &Params { t_d: Dual::seed(0.0, 0), ..q.constants() },
            &per,
            [Dual::cst(-0.2), Dual::cst(0.1)],
        );
        let (x0, x1) = (at(0.0), at(1e-9));
        for j in 0..2 {
            let quotient = (x1[j] - x0[j]) / 1e-9;
            assert!(quotient.abs() > 1.0, "a dead time that moves nothing: {quotient}");
            assert!(
                (dual[j].d[0] - quotient).abs() < 1e-3 * quotient.abs(),
                "{i_w:?} axis {j}: {} against {quotient}",
                dual[j].d[0]
            );
            // The piece of length 0 rounds the value by its last bits.
            assert!((dual[j].v - x0[j]).abs() < 1e-12 * x0[j].abs(), "{} against {}", dual[j].v, x0[j]);
        }
    }
}

/// With hard leg states the period's Jacobian with respect to its start current, by
/// forward mode through every piece, is `e^{A h}` ([`transition`]): a salient machine
/// turning, a dead time and a threshold, currents away from zero.
#[test]
fn the_transition_is_the_steps_jacobian() {
    let q = Params { r: 0.35, l_d: 3.2e-3, l_q: 7.5e-3, k_e: 0.42, t_d: 2e-6, u_th: 1.2, i_w: None };
    let inverter = PwmInverter::default();
    let mut carrier = Carrier::default();
    for (rising, w_e) in [(true, 400.0), (false, -250.0)] {
        let per = Period::new(
            0.3,
            w_e,
            w_e / 2.0,
            400.0,
            halves(&inverter, &mut carrier, [0.3, 0.55, 0.7], rising, 2e-4),
        );
        let next = step(&q.constants(), &per, [Dual::seed(-6.0, 0), Dual::seed(9.0, 1)]);
        let phi = transition(&q, &per);
        let jac = [next[0].d[0], next[0].d[1], next[1].d[0], next[1].d[1]];
        for (a, b) in phi.iter().zip(jac) {
            assert!((a - b).abs() < 1e-12, "{phi:?} against {jac:?}");
        }
        assert!((phi[0] - 1.0).abs() > 1e-3 && phi[1].abs() > 1e-3, "a transition that is not the identity");
    }
}

impl Params<f64> {
    /// The same parameters as dual numbers without derivatives (tests seed what they need).
    pub(crate) fn constants(&self) -> Params<Dual> {
        Params {
            r: Dual::cst(self.r),
            l_d: Dual::cst(self.l_d),
            l_q: Dual::cst(self.l_q),
            k_e: Dual::cst(self.k_e),
            t_d: Dual::cst(self.t_d),
            u_th: Dual::cst(self.u_th),
            i_w: self.i_w.map(Dual::cst),
        }
    }
}

/// A period of the tests: at 0.3 rad, ω_e 400 rad/s, 400 V, duty ratios 0.3, 0.55, 0.7
/// over 200 µs from a rising carrier.
pub(crate) fn test_period() -> Period {
    let mut carrier = Carrier::default();
    let halves = halves(&PwmInverter::default(), &mut carrier, [0.3, 0.55, 0.7], true, 2e-4);
    Period::new(0.3, 400.0, 200.0, 400.0, halves)
}
