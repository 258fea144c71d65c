//! The extended Kalman filter of `(i_d, i_q, R_s, K_e)` (issue 46; Simon, *Optimal State
//! Estimation*, 2006, §13.2; Ljung 1979 for the joint state and parameter form): the
//! current follows the model's exact step, the parameters random walks, the update in
//! Joseph form (Simon §5.1). `greybox::online`'s module `kalman` states the model.

use crate::plant::{Plant, Spm};
use crate::real::Real;
use crate::types::{Estimates, Fault, Field, Sample, Settings};
use num_complex::Complex;

/// `q_i / σ_i` of [`Noise::for_machine`]: the current's model error per sample as a
/// fraction of its measurement noise. 0.05 drove `R_s` 8.9 % low (the truth outside the
/// band at the end in 19 of 20 seeds) over 1.75 s of standstill at zero current under
/// 0.05 A of noise, where the data hold no information on `R_s` and the band widens by the
/// walk: the model error that the filter attributes to the current lets the noise move
/// `R_s`; 0.02, 0.01, 0.005 and 0 gave −3.7, −0.5, +0.6 and +1.0 % (4 seeds; 0.01: −1.4 %,
/// none outside the band, on 20 others).
pub const MODEL_NOISE_RATIO: f64 = 0.01;
/// `q_R / R_s0` of [`Noise::for_machine`] \[1/√s\]: 3 % of `R_s` per √s (chosen on Exp 1
/// ramps of an interior-magnet drive: 2 % lagged the ramp and covered 0.89).
pub const R_S_WALK: f64 = 0.03;
/// `q_K / K_e0` of [`Noise::for_machine`] \[1/√s\]: 0.2 % of `K_e` per √s.
pub const K_E_WALK: f64 = 0.002;

/// The filter's noise model; all standard deviations.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise<T> {
    /// `σ_i`: of each measured current \[A\], positive.
    pub sigma_i: T,
    /// `q_i`: of the current's model error per sample \[A\], at least 0.
    pub q_i: T,
    /// `q_R`: random-walk intensity of `R_s` \[Ω/√s\]; with `relative`, a fraction of the
    /// present `R̂_s` \[1/√s\]. At least 0.
    pub q_r_s: T,
    /// `q_K`: random-walk intensity of `K_e` \[V s/rad/√s\]; with `relative`, a fraction of
    /// the present `|K̂_e|` \[1/√s\]. At least 0.
    pub q_k_e: T,
    /// Of the initial `R_s` \[Ω\], positive.
    pub p0_r_s: T,
    /// Of the initial `K_e` \[V s/rad\], positive.
    pub p0_k_e: T,
    /// The walks in proportion to the present estimates, each estimate taken at least a
    /// hundredth of its initial standard deviation.
    pub relative: bool,
}

impl<T: Real> Noise<T> {
    /// The default noise model of a machine started at `r_s0` \[Ω\], `k_e0` \[V s/rad\] with
    /// current noise `sigma_i` \[A\]: `q_i = 0.01 σ_i`, relative walks of 3 % (`R_s`) and
    /// 0.2 % (`K_e`) per √s, initial standard deviations half of `R_s0` and a fifth of
    /// `K_e0` (a start at 0 counts as 1 Ω and 0.1 V s/rad).
    pub fn for_machine(sigma_i: T, r_s0: T, k_e0: T) -> Self {
        let r = if r_s0 > T::zero() { r_s0 } else { T::one() };
        let k = if k_e0 != T::zero() { k_e0.abs() } else { T::c(0.1) };
        Self {
            sigma_i,
            q_i: T::c(MODEL_NOISE_RATIO) * sigma_i,
            q_r_s: T::c(R_S_WALK),
            q_k_e: T::c(K_E_WALK),
            p0_r_s: T::c(0.5) * r,
            p0_k_e: T::c(0.2) * k,
            relative: true,
        }
    }

    /// The walks' intensities `(q_R, q_K)` at the estimates `r_s` \[Ω\], `k_e` \[V s/rad\].
    pub fn walks_at(&self, r_s: T, k_e: T) -> (T, T) {
        if !self.relative {
            return (self.q_r_s, self.q_k_e);
        }
        let floor = T::c(0.01);
        (self.q_r_s * r_s.abs().max(floor * self.p0_r_s), self.q_k_e * k_e.abs().max(floor * self.p0_k_e))
    }

    /// The first field out of range, if any.
    pub fn invalid(&self) -> Option<Field> {
        let pos = |v: T| v.is_finite() && v > T::zero();
        let nonneg = |v: T| v.is_finite() && v >= T::zero();
        [
            (Field::SigmaI, pos(self.sigma_i)),
            (Field::P0RS, pos(self.p0_r_s)),
            (Field::P0KE, pos(self.p0_k_e)),
            (Field::QI, nonneg(self.q_i)),
            (Field::QRS, nonneg(self.q_r_s)),
            (Field::QKE, nonneg(self.q_k_e)),
        ]
        .into_iter()
        .find(|(_, ok)| !ok)
        .map(|(field, _)| field)
    }
}

type M4<T> = [[T; 4]; 4];

/// The extended Kalman filter, one sample at a time, without allocation or panic. The
/// estimates carry their standard errors.
///
/// Operations per update (surface magnets, f64): the model's step as in
/// [`crate::Mras`] (its transition in closed form), a 2 × 2 inverse, the gain (16
/// multiplications), the Joseph update `(I − K H) P (I − K H)ᵀ + σ² K Kᵀ` (about 300
/// multiplications and additions), the prediction by 2 × 2 blocks (about 60), two square
/// roots.
#[derive(Clone, Copy, Debug)]
pub struct Kalman<T, P = Spm<T>> {
    settings: Settings<T>,
    plant: P,
    noise: Noise<T>,
    /// The state predicted for the next sample, `(i_d, i_q, R_s, K_e)`.
    x: [T; 4],
    /// Its covariance.
    p: M4<T>,
    n: u64,
}

impl<T: Real> Kalman<T, Spm<T>> {
    /// The filter of a surface-magnet machine.
    ///
    /// # Errors
    /// The first field out of range ([`Settings::invalid`], [`Noise::invalid`]).
    pub fn spm(settings: Settings<T>, noise: Noise<T>) -> Result<Self, Field> {
        Self::new(settings, Spm::new(&settings), noise)
    }
}

impl<T: Real, P: Plant<T>> Kalman<T, P> {
    /// The filter of the machine of `settings` (`n_p`, `h`, the initial `k_e0`, `r_s0`;
    /// the MRAS's gains are not used) stepping `plant`, with the noise model `noise`.
    ///
    /// # Errors
    /// The first field out of range ([`Settings::invalid`], [`Noise::invalid`]).
    pub fn new(settings: Settings<T>, plant: P, noise: Noise<T>) -> Result<Self, Field> {
        if let Some(field) = noise.invalid().or(settings.invalid()) {
            return Err(field);
        }
        let zero = T::zero();
        Ok(Self { settings, plant, noise, x: [zero; 4], p: [[zero; 4]; 4], n: 0 })
    }

    /// The settings.
    pub fn settings(&self) -> &Settings<T> {
        &self.settings
    }

    /// Takes sample `s`: updates the estimates with the measured `i[k]`, then predicts
    /// `i[k+1]`. The first sample starts the filter at the measured current and the
    /// configured `k_e0`, `r_s0`.
    ///
    /// # Errors
    /// [`Fault::NonFinite`], [`Fault::Step`], [`Fault::Singular`] (the innovation's
    /// covariance), [`Fault::NotFinite`]; the filter is then unchanged.
    pub fn update(&mut self, s: &Sample<T>) -> Result<Estimates<T>, Fault<T, P::Error>> {
        let sample = self.n;
        if let Some(channel) = s.non_finite() {
            return Err(Fault::NonFinite { channel, sample });
        }
        let zero = T::zero();
        let s2 = self.noise.sigma_i * self.noise.sigma_i;
        // Worked on copies, committed at the end: a failed update leaves the filter as it was.
        let (mut x, mut p) = (self.x, self.p);
        let mut nis = zero;
        let nu = if self.n == 0 {
            x = [s.i_d, s.i_q, self.settings.r_s0, self.settings.k_e0];
            p = [[zero; 4]; 4];
            let (p0r, p0k) = (self.noise.p0_r_s, self.noise.p0_k_e);
            (p[0][0], p[1][1], p[2][2], p[3][3]) = (s2, s2, p0r * p0r, p0k * p0k);
            [zero; 2]
        } else {
            let nu = [s.i_d - x[0], s.i_q - x[1]];
            // S = H P Hᵀ + σ² I and its inverse.
            let (s00, s01, s10, s11) = (p[0][0] + s2, p[0][1], p[1][0], p[1][1] + s2);
            let det = s00 * s11 - s10 * s01;
            if !(det.is_finite() && det != zero) {
                return Err(Fault::Singular { sample, det });
            }
            let inv = [[s11 / det, -s01 / det], [-s10 / det, s00 / det]];
            nis = nu[0] * (inv[0][0] * nu[0] + inv[0][1] * nu[1])
                + nu[1] * (inv[1][0] * nu[0] + inv[1][1] * nu[1]);
            // K = P Hᵀ S⁻¹ (4 × 2).
            let mut k = [[zero; 2]; 4];
            for (r, row) in k.iter_mut().enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    *v = p[r][0] * inv[0][c] + p[r][1] * inv[1][c];
                }
            }
            for (xr, kr) in x.iter_mut().zip(&k) {
                *xr = *xr + (kr[0] * nu[0] + kr[1] * nu[1]);
            }
            p = joseph(&p, &k, s2);
            nu
        };
        x[2] = x[2].max(zero);
        let (r_s, k_e) = (x[2], x[3]);
        let mut out = Estimates::at(k_e, r_s, self.settings.n_p, nu[0], nu[1], true);
        out.k_e_se = p[3][3].max(zero).sqrt();
        out.r_s_se = p[2][2].max(zero).sqrt();
        out.nis = nis;
        let (x, p) = self.predict(x, p, s).map_err(|error| Fault::Step { sample, error })?;
        if !(x.iter().all(|v| v.is_finite()) && p.iter().flatten().all(|v| v.is_finite())) {
            return Err(Fault::NotFinite { sample, k_e, r_s });
        }
        (self.x, self.p) = (x, p);
        self.n += 1;
        Ok(out)
    }

    /// The prediction of `(x, P)` to the next sample: `x ← f(x)`, `P ← F P Fᵀ + Q`, with
    /// `F = [[Φ, B], [0, I]]`, `B = [∂i/∂R_s, ∂i/∂K_e]`, by 2 × 2 blocks.
    fn predict(&self, x: [T; 4], p: M4<T>, s: &Sample<T>) -> Result<([T; 4], M4<T>), P::Error> {
        let (i, r_s, k_e) = (Complex::new(x[0], x[1]), x[2], x[3]);
        let (st, phi) = self.plant.step_transition(i, k_e, r_s, s)?;
        let b = [[st.phi_r.re, st.phi_k.re], [st.phi_r.im, st.phi_k.im]];
        let block = |r: usize, c: usize| [[p[r][c], p[r][c + 1]], [p[r + 1][c], p[r + 1][c + 1]]];
        let (p_ii, p_ip, p_pp) = (block(0, 0), block(0, 2), block(2, 2));
        // M = Φ P_ii + B P_ipᵀ, N = Φ P_ip + B P_pp; top = M Φᵀ + N Bᵀ.
        let m = add(&mul(&phi, &p_ii), &mul(&b, &transpose(&p_ip)));
        let n = add(&mul(&phi, &p_ip), &mul(&b, &p_pp));
        let top = add(&mul(&m, &transpose(&phi)), &mul(&n, &transpose(&b)));
        let half = T::c(0.5);
        let q_i = self.noise.q_i * self.noise.q_i;
        let (q_r, q_k) = self.noise.walks_at(r_s, k_e);
        let h = self.settings.h;
        let sym = |a: [[T; 2]; 2], d0: T, d1: T| {
            let off = (a[0][1] + a[1][0]) * half;
            [[a[0][0] + d0, off], [off, a[1][1] + d1]]
        };
        let top = sym(top, q_i, q_i);
        let pp = sym(p_pp, q_r * q_r * h, q_k * q_k * h);
        let out = [
            [top[0][0], top[0][1], n[0][0], n[0][1]],
            [top[1][0], top[1][1], n[1][0], n[1][1]],
            [n[0][0], n[1][0], pp[0][0], pp[0][1]],
            [n[0][1], n[1][1], pp[1][0], pp[1][1]],
        ];
        Ok(([st.next.re, st.next.im, r_s, k_e], out))
    }
}

/// `(I − K H) P (I − K H)ᵀ + σ² K Kᵀ` with `H = [I₂ 0]`, symmetrised.
fn joseph<T: Real>(p: &M4<T>, k: &[[T; 2]; 4], s2: T) -> M4<T> {
    let zero = T::zero();
    // A = I − K H: A[r][c] = δ_rc − K[r][c] for c < 2.
    let mut a = [[zero; 4]; 4];
    for (r, row) in a.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            let delta = if r == c { T::one() } else { zero };
            *v = if c < 2 { delta - k[r][c] } else { delta };
        }
    }
    let mut ap = [[zero; 4]; 4];
    for r in 0..4 {
        for c in 0..4 {
            ap[r][c] = (0..4).fold(zero, |acc, j| acc + a[r][j] * p[j][c]);
        }
    }
    let mut out = [[zero; 4]; 4];
    for r in 0..4 {
        for c in r..4 {
            let v = (0..4).fold(zero, |acc, j| acc + ap[r][j] * a[c][j])
                + s2 * (k[r][0] * k[c][0] + k[r][1] * k[c][1]);
            out[r][c] = v;
            out[c][r] = v;
        }
    }
    out
}

fn mul<T: Real>(a: &[[T; 2]; 2], b: &[[T; 2]; 2]) -> [[T; 2]; 2] {
    let e = |r: usize, c: usize| a[r][0] * b[0][c] + a[r][1] * b[1][c];
    [[e(0, 0), e(0, 1)], [e(1, 0), e(1, 1)]]
}

fn add<T: Real>(a: &[[T; 2]; 2], b: &[[T; 2]; 2]) -> [[T; 2]; 2] {
    [[a[0][0] + b[0][0], a[0][1] + b[0][1]], [a[1][0] + b[1][0], a[1][1] + b[1][1]]]
}

fn transpose<T: Real>(a: &[[T; 2]; 2]) -> [[T; 2]; 2] {
    [[a[0][0], a[1][0]], [a[0][1], a[1][1]]]
}
