//! Piecewise-linear signals of time: references, load torques, temperatures, parameter
//! ramps. A list of `(t, value)` breakpoints, linear between them and constant outside.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// A piecewise-linear function of time: breakpoints `(t [s], value [unit])` in increasing
/// time, linear in between, held before the first and after the last. An empty profile is
/// 0 everywhere.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Profile(pub Vec<(f64, f64)>);

impl Profile {
    /// The constant `value`.
    pub fn constant(value: f64) -> Self {
        Self(vec![(0.0, value)])
    }

    /// The value at time `t` \[s\].
    pub fn at(&self, t: f64) -> f64 {
        let p = &self.0;
        match p.iter().position(|&(tk, _)| tk > t) {
            None => p.last().map_or(0.0, |x| x.1),
            Some(0) => p[0].1,
            Some(j) => {
                let ((t0, v0), (t1, v1)) = (p[j - 1], p[j]);
                if t1 > t0 { v0 + (v1 - v0) * (t - t0) / (t1 - t0) } else { v1 }
            }
        }
    }

    /// The slope at time `t` \[unit/s\] (0 outside the breakpoints and on a jump).
    pub fn slope(&self, t: f64) -> f64 {
        let p = &self.0;
        match p.iter().position(|&(tk, _)| tk > t) {
            None | Some(0) => 0.0,
            Some(j) => {
                let ((t0, v0), (t1, v1)) = (p[j - 1], p[j]);
                if t1 > t0 { (v1 - v0) / (t1 - t0) } else { 0.0 }
            }
        }
    }

    /// Checks that every breakpoint is finite and the times do not decrease.
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming the profile (`name`) and the breakpoint.
    pub fn validate(&self, name: &str) -> Result<()> {
        let bad = |reason: String| Error::InvalidOption { option: name.into(), reason };
        for (j, &(t, v)) in self.0.iter().enumerate() {
            if !(t.is_finite() && v.is_finite()) {
                return Err(bad(format!("breakpoint {j} ({t}, {v}) is not finite")));
            }
            if j > 0 && t < self.0[j - 1].0 {
                return Err(bad(format!("breakpoint {j} at t = {t} s precedes the one before it")));
            }
        }
        Ok(())
    }

    /// Back-and-forth trapezoidal moves: for each level `w` \[unit\], a ramp up in `ramp` s,
    /// a hold of `hold` s, a ramp to `−w` through zero, a hold, a ramp back to 0 and a
    /// `dwell` at rest; starting at `start` s.
    pub fn back_and_forth(start: f64, levels: &[f64], ramp: f64, hold: f64, dwell: f64) -> Self {
        let mut p = vec![(0.0, 0.0), (start, 0.0)];
        let mut t = start;
        for &w in levels {
            for (dt, v) in [(ramp, w), (hold, w), (2.0 * ramp, -w), (hold, -w), (ramp, 0.0), (dwell, 0.0)] {
                t += dt;
                p.push((t, v));
            }
        }
        Self(p)
    }
}

#[cfg(test)]
mod tests {
    use super::Profile;

    #[test]
    fn interpolates_and_holds() {
        let p = Profile(vec![(1.0, 0.0), (2.0, 10.0), (2.0, 20.0), (3.0, 20.0)]);
        assert_eq!(p.at(0.0), 0.0);
        assert_eq!(p.at(1.5), 5.0);
        assert_eq!(p.at(2.5), 20.0);
        assert_eq!(p.at(9.0), 20.0);
        assert_eq!(p.slope(1.5), 10.0);
        assert_eq!(Profile::default().at(1.0), 0.0);
        assert!(Profile(vec![(1.0, 0.0), (0.5, 1.0)]).validate("x").is_err());
    }
}
