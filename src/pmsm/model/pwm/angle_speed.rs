//! The scale between a log's interval-mean speeds and its angle: under PWM the rotor's
//! speed sags below the chord of its sampled values inside every period, so the trapezoid
//! `(w_m[k] + w_m[k+1])/2` overstates the mean speed the back-EMF and the frame's rotation
//! take; the logged angle measures that mean.
//!
//! Why: the zero vectors at both ends of a half carrier let the back-EMF pull `i_q` down, so
//! the torque is low early and high late in every period (rising and falling halves alike),
//! and the speed lies below its chord by about `n_p² ψ_f² h² / (16 L_q J)` of itself. On
//! motulator's PWM logs (which log the instantaneous speed) that is 3–9 ppm: the K_e the
//! PWM fit found was low by as much, at 13–25 of its noise-free standard errors, while the
//! averaged (zero-order-hold) logs, without zero-vector dips, gave it exactly.
//!
//! The sag is not one scale of the speed: over the shared 3 µs log's moves it is 6–22 ppm,
//! larger where `R_s i_q` adds to the back-EMF in `ū_q`. A second regressor, the period's
//! q voltage, fitted the angle better (windowed residual 1.0 ppm for 2.9) but moved that
//! log's `r_s` from +9 to +12 ppm and stopped a 6 kHz log's fit short of its minimum
//! (`not_stationary`): not taken.

/// Largest relative scale taken: a larger one is no sag inside the period but a speed and
/// an angle that disagree (units, a filter's gain), which the setup checks name; the
/// speeds are then taken as logged.
pub(crate) const MAX_SCALE: f64 = 1e-3;

/// The factor `1 + ε` that turns the interval means of `w_m` \[rad/s\] into the mean speeds
/// of the angle `theta_m` \[rad, mechanical\] (both length N, sample time `h` \[s\]):
/// `ε = Σ_k s_k (Δθ_k − w̄_k h) / Σ_k |w̄_k| h`, `Δθ_k` the wrapped angle step, `w̄_k` the
/// trapezoid, `s_k` its sign (intervals at rest left out). The sum telescopes within each
/// run of one sign, so the angle's rounding or an encoder's quantization enters at the runs'
/// ends only, where a per-interval `Δθ/h` would carry it in every interval. 1 when the log
/// has no moving interval, when the factor is not a number, or when `|ε|` exceeds
/// [`MAX_SCALE`].
pub(crate) fn angle_speed_scale(theta_m: &[f64], w_m: &[f64], h: f64) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (t, w) in theta_m.windows(2).zip(w_m.windows(2)) {
        let mean = super::super::interval::mean_speed(w);
        if mean == 0.0 {
            continue;
        }
        let d = t[1] - t[0];
        let step = d.sin().atan2(d.cos());
        num += mean.signum() * (step - mean * h);
        den += mean.abs() * h;
    }
    let eps = num / den;
    if eps.is_finite() && eps.abs() <= MAX_SCALE { 1.0 + eps } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A speed that sags by 9 ppm inside every interval of a back-and-forth move is found
    /// from the angle to 1e-9; a speed in the wrong unit is taken as logged; a log at rest
    /// gives 1.
    #[test]
    fn the_angle_gives_the_mean_speed_of_every_interval() {
        let (h, n, eps) = (1e-4, 20_000, -9e-6);
        let w: Vec<f64> = (0..n).map(|k| 200.0 * (k as f64 * h * 3.0).sin()).collect();
        let mut theta = vec![0.3];
        for k in 0..n - 1 {
            let mean = 0.5 * (w[k] + w[k + 1]) * (1.0 + eps);
            let next = theta[k] + mean * h;
            theta.push(next.sin().atan2(next.cos()));
        }
        let s = angle_speed_scale(&theta, &w, h);
        assert!((s - (1.0 + eps)).abs() < 1e-9, "{s}");
        let rpm: Vec<f64> = w.iter().map(|x| x * 60.0 / std::f64::consts::TAU).collect();
        assert_eq!(angle_speed_scale(&theta, &rpm, h), 1.0);
        assert_eq!(angle_speed_scale(&[0.1; 10], &[0.0; 10], h), 1.0);
    }
}
