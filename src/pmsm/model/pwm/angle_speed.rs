//! The mean speed inside each period from a log's angle: under PWM the rotor's speed sags
//! below the chord of its sampled values inside every period, so the trapezoid
//! `w̄_k = (w_m[k] + w_m[k+1])/2` overstates the mean speed the back-EMF and the frame's
//! rotation take; the logged angle measures that mean.
//!
//! Why: the zero vectors at both ends of a half carrier let the back-EMF pull `i_q` down, so
//! the torque is low early and high late in every period (rising and falling halves alike),
//! and the speed lies below its chord by about `n_p² ψ_f² h² / (16 L_q J)` of itself. On
//! motulator's PWM logs (which log the instantaneous speed) that is 3–9 ppm: the K_e the
//! PWM fit found was low by as much, at 13–25 of its noise-free standard errors, while the
//! averaged (zero-order-hold) logs, without zero-vector dips, gave it exactly.
//!
//! The sag is not one scale of the speed. On the shared 3 µs and IPM logs regenerated with
//! every column to 17 digits (the same motulator 0.18 scenarios), the angle step beyond the
//! chord, `Δθ_k − w̄_k h`, is on both to 98.9 % of its variance
//! `c₀ w̄_k h + c₁ Δw_k + c₂ w̄_k h |ī_q,k|`: a scale of the speed (−4.4e-6 and −8.3e-6 alone),
//! a lag behind the acceleration (`c₁` −1.2e-7 and −9.0e-8 s; with the acceleration's own
//! term, [`super::acceleration`], it had made up for 80 % of that term on the IPM log), and
//! a share growing with the torque current (`c₂` −2.0e-7 per A on the IPM, where the
//! reluctance torque's ripple adds). The period's mean speed is
//! `w̄_k (1 + c₀ + c₂ |ī_q,k|) + c₁ a_k`, `a_k = Δw_k / h`, with `c` the least-squares fit
//! over the moving intervals of the log itself: each regressor changes slowly from one
//! interval to the next, so the angle's rounding (the difference of two roundings in every
//! step) nearly cancels in their sums, as it telescopes in a run of one sign. With it the
//! regenerated IPM log's fit is within |z| 2.9 of the truth (4.4 with `c₀, c₁` alone), and
//! within 1.0 with the exact angle step as the mean speed.

/// Largest relative share of the speed taken (`|c₀|`, `|c₂| max |ī_q|`): a larger one is
/// no sag inside the period but a speed and an angle that disagree (units, a filter's
/// gain), which the setup checks name; the speeds are then taken as logged.
pub(crate) const MAX_SCALE: f64 = 1e-3;

/// The fit of the mean speed inside each period ([`MeanSpeed::fit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MeanSpeed {
    /// `c₀` \[1\], `c₁` \[s\], `c₂` \[1/A\] (module documentation).
    c: [f64; 3],
}

impl MeanSpeed {
    /// The speeds as logged (`c = 0`).
    pub(crate) const LOGGED: MeanSpeed = MeanSpeed { c: [0.0; 3] };

    /// The least-squares fit of `Δθ_k − w̄_k h` on `w̄_k h`, `Δw_k` and `w̄_k h |ī_q,k|` over the
    /// intervals of `theta_m` \[rad, mechanical\], `w_m` \[rad/s\] and `i_q` \[A\] (length N, sample
    /// time `h` \[s\]) whose trapezoid is not 0 (`Δθ` the wrapped angle step). Where the log
    /// has fewer than three moving intervals, the normal equations are singular or give no
    /// number, or the fit's scale exceeds [`MAX_SCALE`] or its lag a period, the scale `c₀`
    /// alone (the angle steps beyond the chords over the chords' sum, within a run of one
    /// sign a telescoping sum); the speeds as logged ([`Self::LOGGED`]) where that too
    /// exceeds [`MAX_SCALE`] or the log does not move.
    pub(crate) fn fit(theta_m: &[f64], w_m: &[f64], i_q: &[f64], h: f64) -> MeanSpeed {
        let mut a = nalgebra::Matrix3::<f64>::zeros();
        let mut b = nalgebra::Vector3::<f64>::zeros();
        let (mut moving, mut i_max, mut ratio) = (0, 0.0_f64, (0.0, 0.0));
        for k in 0..theta_m.len().min(w_m.len()).min(i_q.len()).saturating_sub(1) {
            let mean = super::super::interval::mean_speed(&w_m[k..k + 2]);
            if mean == 0.0 {
                continue;
            }
            let d = theta_m[k + 1] - theta_m[k];
            let r = d.sin().atan2(d.cos()) - mean * h;
            let i = 0.5 * (i_q[k] + i_q[k + 1]).abs();
            let x = nalgebra::Vector3::new(mean * h, w_m[k + 1] - w_m[k], mean * h * i);
            a += x * x.transpose();
            b += x * r;
            moving += 1;
            i_max = i_max.max(i);
            ratio = (ratio.0 + mean.signum() * r, ratio.1 + mean.abs() * h);
        }
        let full = match a.lu().solve(&b) {
            Some(c) if moving >= 3 && c.iter().all(|v| v.is_finite()) => Some([c[0], c[1], c[2]]),
            _ => None,
        }
        .filter(|c| c[0].abs() <= MAX_SCALE && c[1].abs() <= h && c[2].abs() * i_max <= MAX_SCALE);
        // The scale alone where the three do not fit (a speed without acceleration makes
        // the normal equations singular): the angle steps beyond the chords over the
        // chords' sum, `Σ s_k (Δθ_k − w̄_k h) / Σ |w̄_k| h`, `s_k` the chord's sign.
        let scale = ratio.0 / ratio.1;
        let alone = (scale.is_finite() && scale.abs() <= MAX_SCALE).then_some([scale, 0.0, 0.0]);
        full.or(alone).map_or(MeanSpeed::LOGGED, |c| MeanSpeed { c })
    }

    /// The mean speed \[rad/s\] over the interval from `w` = `(w_m[k], w_m[k+1])` \[rad/s\] at
    /// torque currents `i_q` = `(i_q[k], i_q[k+1])` \[A\], sample time `h` \[s\].
    pub(crate) fn mean(&self, w: &[f64], i_q: &[f64], h: f64) -> f64 {
        let i = 0.5 * (i_q[0] + i_q[1]).abs();
        super::super::interval::mean_speed(w) * (1.0 + self.c[0] + self.c[2] * i)
            + self.c[1] * (w[1] - w[0]) / h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A speed whose angle sags by a scale, a lag behind the acceleration and a share of the
    /// torque current is found from an angle rounded to 7 digits; a constant speed gets its
    /// scale alone; a speed in the wrong unit is taken as logged; so is a log at rest.
    #[test]
    fn the_angle_gives_the_mean_speed_of_every_interval() {
        let (h, n) = (1e-4, 40_000);
        let truth = MeanSpeed { c: [-8e-6, -9e-8, -2e-7] };
        let w: Vec<f64> = (0..n).map(|k| 200.0 * (k as f64 * h * 3.0).sin()).collect();
        let i_q: Vec<f64> = (0..n).map(|k| 6.0 * (k as f64 * h * 3.0).cos()).collect();
        let mut exact = vec![0.3];
        for k in 0..n - 1 {
            let next = exact[k] + truth.mean(&w[k..k + 2], &i_q[k..k + 2], h) * h;
            exact.push(next);
        }
        let round = |x: f64| {
            let t = x.sin().atan2(x.cos());
            let scale = 10f64.powi(6 - t.abs().log10().floor() as i32);
            (t * scale).round() / scale
        };
        let theta: Vec<f64> = exact.iter().map(|x| round(*x)).collect();
        let found = MeanSpeed::fit(&theta, &w, &i_q, h);
        for k in (0..n - 1).step_by(97) {
            let (a, b) =
                (found.mean(&w[k..k + 2], &i_q[k..k + 2], h), truth.mean(&w[k..k + 2], &i_q[k..k + 2], h));
            assert!((a - b).abs() <= 2e-7 * b.abs().max(1.0), "{k}: {a} against {b} ({found:?})");
        }
        // A speed without acceleration: the scale alone.
        let flat = vec![150.0; 2000];
        let mut turned = vec![0.2];
        for k in 0..1999 {
            let next = turned[k] + 150.0 * (1.0 - 9e-6) * h;
            turned.push(next.sin().atan2(next.cos()));
        }
        let alone = MeanSpeed::fit(&turned, &flat, &[1.0; 2000], h);
        assert!((alone.mean(&flat[..2], &[1.0; 2], h) - 150.0 * (1.0 - 9e-6)).abs() < 1e-9, "{alone:?}");
        let rpm: Vec<f64> = w.iter().map(|x| x * 60.0 / std::f64::consts::TAU).collect();
        assert_eq!(MeanSpeed::fit(&theta, &rpm, &i_q, h), MeanSpeed::LOGGED);
        assert_eq!(MeanSpeed::fit(&[0.1; 10], &[0.0; 10], &[0.0; 10], h), MeanSpeed::LOGGED);
    }
}
