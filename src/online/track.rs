//! The MRAS run over a whole log: the estimates' trajectory (backs `greybox track`).

use super::config::MrasConfig;
use super::mras::{Estimates, Mras, Sample};
use crate::data::Experiment;
use crate::error::Result;
use crate::pmsm::DqView;
use serde::{Deserialize, Serialize};

/// The estimates over time, one point per sample interval (all vectors of one length).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Time of each point `t_k = k h` \[s\], length M.
    pub t: Vec<f64>,
    /// K̂_e after the sample at `t_k` \[V s/rad\], length M.
    pub k_e: Vec<f64>,
    /// R̂_s after the sample at `t_k` \[Ω\], length M.
    pub r_s: Vec<f64>,
    /// The estimates after the last sample.
    pub final_estimate: Estimates,
}

impl Trajectory {
    /// At most `max_points` points, evenly strided from the first, always keeping the
    /// last (`max_points` 0 or 1: the last point only; an empty trajectory stays empty).
    /// `final_estimate` is kept.
    pub fn decimate(&self, max_points: usize) -> Trajectory {
        let n = self.t.len();
        let idx: Vec<usize> = match (n, max_points) {
            (0, _) => Vec::new(),
            (_, m) if m >= n => (0..n).collect(),
            (_, 0 | 1) => vec![n - 1],
            (_, m) => {
                let stride = (n - 1).div_ceil(m - 1);
                let mut v: Vec<usize> = (0..n).step_by(stride).collect();
                if v.last() != Some(&(n - 1)) {
                    v.push(n - 1);
                }
                v
            }
        };
        let pick = |x: &[f64]| idx.iter().map(|&k| x[k]).collect();
        Trajectory {
            t: pick(&self.t),
            k_e: pick(&self.k_e),
            r_s: pick(&self.r_s),
            final_estimate: self.final_estimate,
        }
    }
}

/// Runs the MRAS over a PMSM log (channels `id, iq, ud, uq, w_m` through [`DqView`]):
/// sample k pairs `i[k]` with `u[k]` and the interval-mean speed
/// `(ω_m[k] + ω_m[k+1])/2` of the step to `i[k+1]` (MODEL.md §4), k = 0..N−2.
/// The sample time is the log's (`config.h` is replaced by it).
///
/// # Errors
/// Those of [`DqView::try_new`] (a missing channel, too short a log) and
/// [`DqView::terminal_voltage`] (a log with only the voltage reference), of
/// [`MrasConfig::validate`] and of [`Mras::update`] (naming the sample).
pub fn track(e: &Experiment, config: &MrasConfig) -> Result<Trajectory> {
    let v = DqView::try_new(e)?;
    let mut mras = Mras::try_new(MrasConfig { h: e.h(), ..config.clone() })?;
    let (u_d, u_q) = v.terminal_voltage()?;
    let (i_d, i_q, w_m) = (v.i_d(), v.i_q(), v.w_m());
    let m = v.len() - 1;
    let mut out = Trajectory {
        t: Vec::with_capacity(m),
        k_e: Vec::with_capacity(m),
        r_s: Vec::with_capacity(m),
        final_estimate: mras.output(),
    };
    for k in 0..m {
        let s =
            Sample { i_d: i_d[k], i_q: i_q[k], u_d: u_d[k], u_q: u_q[k], w_m: 0.5 * (w_m[k] + w_m[k + 1]) };
        let est = mras.update(&s)?;
        out.t.push(e.t0() + k as f64 * e.h());
        out.k_e.push(est.k_e);
        out.r_s.push(est.r_s);
        out.final_estimate = est;
    }
    Ok(out)
}
