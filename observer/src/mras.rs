//! The sampled MRAS observer of `K_e` and `R_s` (thesis 5.1, MODEL.md §7), one sample at a
//! time: exact in the state, implicit (backward Euler) in the parameters. The design and
//! its discretisation are derived in `greybox::online`'s documentation (the module `mras`).

use crate::plant::{Plant, Spm, Step};
use crate::real::Real;
use crate::types::{Adaptation, Estimates, Fault, Field, Sample, Settings};
use num_complex::Complex;

/// Share of the mean information below which a sample does not update it
/// ([`Adaptation::Normalised`]).
pub const INFORMATIVE: f64 = 0.1;

/// What [`Mras::compute_output`] found for one sample: the estimates, and the observer's
/// next state for [`Mras::advance`].
#[derive(Clone, Copy, Debug)]
pub struct MrasOutput<T> {
    /// The estimates after the adaptation at `t_k`.
    pub estimates: Estimates<T>,
    sample: u64,
    next: State<T>,
}

/// The observer's state between samples.
#[derive(Clone, Copy, Debug, Default)]
struct State<T> {
    i_hat: Complex<T>,
    phi_k: Complex<T>,
    phi_r: Complex<T>,
    psi_k: Complex<T>,
    k_e: T,
    r_s: T,
    p_k: T,
    p_r: T,
}

/// The MRAS observer: state `î`, parameters `(K̂_e, R̂_s)`, the model `P` (the surface
/// magnets' [`Spm`] by default). [`Mras::update`] takes a [`Sample`], corrects and adapts at
/// `t_k`, and steps to `t_{k+1}`; split as [`Mras::compute_output`] (`&self`) and
/// [`Mras::advance`] so a controller can use the estimates before the state moves. No
/// allocation, no panic.
///
/// Operations per update (surface magnets, f64): one `sin`/`cos` pair of the frame's
/// rotation, one `exp` of the decay, one complex `expm1` (a `sin`/`cos` pair, a `sin`,
/// `exp`, `expm1`) and one complex division in `(1 − e^{−w})/w`, one `hypot`
/// (`|w|`), and about 150 multiplications and additions; with the stator hold, a second
/// complex `expm1` and two divisions.
#[derive(Clone, Copy, Debug)]
pub struct Mras<T, P = Spm<T>> {
    settings: Settings<T>,
    plant: P,
    /// `1 − e^{−f h}`: the share of the error the observer takes per period.
    kappa: T,
    state: State<T>,
    n: u64,
    last: Estimates<T>,
}

impl<T: Real> Mras<T, Spm<T>> {
    /// The surface-magnet observer of `settings`.
    ///
    /// # Errors
    /// The first field out of range ([`Settings::invalid`]).
    pub fn spm(settings: Settings<T>) -> Result<Self, Field> {
        Self::new(settings, Spm::new(&settings))
    }
}

impl<T: Real, P: Plant<T>> Mras<T, P> {
    /// The observer of `settings` stepping `plant`, started at `k_e0`, `r_s0` and, at the
    /// first sample, at the measured current.
    ///
    /// # Errors
    /// The first field out of range ([`Settings::invalid`]).
    pub fn new(settings: Settings<T>, plant: P) -> Result<Self, Field> {
        if let Some(field) = settings.invalid() {
            return Err(field);
        }
        let kappa = -(-settings.f * settings.h).exp_m1();
        let state = State { k_e: settings.k_e0, r_s: settings.r_s0, ..State::default() };
        let last = Estimates::at(settings.k_e0, settings.r_s0, settings.n_p, T::zero(), T::zero(), false);
        Ok(Self { settings, plant, kappa, state, n: 0, last })
    }

    /// The settings.
    pub fn settings(&self) -> &Settings<T> {
        &self.settings
    }

    /// The model.
    pub fn plant(&self) -> &P {
        &self.plant
    }

    /// The estimates after the last update (the initial ones before any).
    pub fn output(&self) -> Estimates<T> {
        self.last
    }

    /// The prediction `(î_d, î_q)` \[A\] of the current at the next sample.
    pub fn predicted_current(&self) -> (T, T) {
        (self.state.i_hat.re, self.state.i_hat.im)
    }

    /// Takes sample k and moves the observer to `t_{k+1}`: [`Mras::compute_output`] then
    /// [`Mras::advance`]. Returns the estimates after the adaptation at `t_k`.
    ///
    /// # Errors
    /// Those of [`Mras::compute_output`]; the observer is then unchanged.
    pub fn update(&mut self, s: &Sample<T>) -> Result<Estimates<T>, Fault<T, P::Error>> {
        let out = self.compute_output(s)?;
        self.advance(&out)?;
        Ok(out.estimates)
    }

    /// The error `e = i[k] − î[k]`, the implicit adaptation of `K̂_e` (and of `R̂_s` while
    /// `|i_d|` exceeds the threshold) and the exact step to `t_{k+1}`, without changing the
    /// observer. The first sample starts the observer at `i[0]` and adapts nothing.
    ///
    /// # Errors
    /// [`Fault::NonFinite`] (a NaN or infinite channel), [`Fault::Step`] (the model's step),
    /// [`Fault::Singular`], [`Fault::NotFinite`] (not expected).
    pub fn compute_output(&self, s: &Sample<T>) -> Result<MrasOutput<T>, Fault<T, P::Error>> {
        let sample = self.n;
        if let Some(channel) = s.non_finite() {
            return Err(Fault::NonFinite { channel, sample });
        }
        let st = &self.state;
        let i = Complex::new(s.i_d, s.i_q);
        let i_hat = if self.n == 0 { i } else { st.i_hat };
        let e = i - i_hat;
        let active = self.n > 0 && self.settings.r_s_adapts(s.i_d);
        let (g_k, g_r, p_k, p_r) = self.gains(i, active);
        let (dk, dr) = self.adaptation(e, g_k, g_r)?;
        let (k_e, r_s) = (st.k_e + dk, (st.r_s + dr).max(T::zero()));
        // The last step re-taken with the new parameters (first order), then corrected.
        let i_post = i_hat + st.phi_k * dk + st.phi_r * (r_s - st.r_s);
        let x = i_post + (i - i_post) * self.kappa;
        let relay = self.settings.adaptation == Adaptation::Relay;
        let Step { next, phi_k, phi_r, psi_k } =
            self.plant.step(x, k_e, r_s, s, relay).map_err(|error| Fault::Step { sample, error })?;
        if !(next.re.is_finite() && next.im.is_finite() && k_e.is_finite() && r_s.is_finite()) {
            return Err(Fault::NotFinite { sample, k_e, r_s });
        }
        Ok(MrasOutput {
            estimates: Estimates::at(k_e, r_s, self.settings.n_p, e.re, e.im, active),
            sample,
            next: State { i_hat: next, phi_k, phi_r, psi_k, k_e, r_s, p_k, p_r },
        })
    }

    /// Commits an output of [`Mras::compute_output`] computed at the present state.
    ///
    /// # Errors
    /// [`Fault::Stale`] when `out` belongs to another sample; the observer is unchanged.
    pub fn advance(&mut self, out: &MrasOutput<T>) -> Result<(), Fault<T, P::Error>> {
        if out.sample != self.n {
            return Err(Fault::Stale { output: out.sample, observer: self.n });
        }
        self.state = out.next;
        self.n += 1;
        self.last = out.estimates;
        Ok(())
    }

    /// The gains `(γ_K, γ_R)` at current `i` (`R̂_s` adapting when `r_active`) and the mean
    /// information `(P̄_K, P̄_R)` after this sample (unchanged but under
    /// [`Adaptation::Normalised`]).
    fn gains(&self, i: Complex<T>, r_active: bool) -> (T, T, T, T) {
        let (cfg, st) = (&self.settings, &self.state);
        if cfg.adaptation != Adaptation::Normalised {
            // −γ_Rs L_s/|i| maps the thesis' gain onto the sensitivity φ_R ≈ −h i/L_s; |i| > 0
            // whenever |i_d| exceeds the threshold.
            let g_r = if r_active { -cfg.gamma_rs * cfg.l_s / i.norm() } else { T::zero() };
            return (cfg.gamma_ke, g_r, st.p_k, st.p_r);
        }
        // P̄ ← P̄ + (h/τ)(|φ|² − P̄), started at the first value; γ = (h/τ)/P̄. A sample with
        // less than INFORMATIVE of the mean information leaves P̄ as it is: without that, P̄
        // decays at standstill (φ_K = 0) and the gain winds up, the classic failure of
        // forgetting without excitation (Ioannou & Sun 1996, 4.11; Fortescue, Kershenbaum &
        // Ydstie, Automatica 17 (1981) 831–835).
        let mean = |p: T, info: T, a: T| match p > T::zero() {
            false => info,
            true if info >= T::c(INFORMATIVE) * p => p + a * (info - p),
            true => p,
        };
        let gain = |p: T, a: T| if p > T::zero() && p.is_finite() { a / p } else { T::zero() };
        let (a_k, a_r) = (cfg.h / cfg.tau_ke, cfg.h / cfg.tau_rs);
        let p_k = mean(st.p_k, st.phi_k.norm_sqr(), a_k);
        let p_r = if r_active { mean(st.p_r, st.phi_r.norm_sqr(), a_r) } else { st.p_r };
        (gain(p_k, a_k), if r_active { gain(p_r, a_r) } else { T::zero() }, p_k, p_r)
    }

    /// `(ΔK̂_e, ΔR̂_s)` from `(I + Γ Re(ΨᴴΦ)) Δθ = Γ Re(Ψᴴ e)` with `Γ = diag(g_k, g_r)`.
    fn adaptation(&self, e: Complex<T>, g_k: T, g_r: T) -> Result<(T, T), Fault<T, P::Error>> {
        let dot = |a: Complex<T>, b: Complex<T>| a.re * b.re + a.im * b.im; // Re(ā b)
        let (psi_k, phi_k, phi_r) = (self.state.psi_k, self.state.phi_k, self.state.phi_r);
        let m = [
            [g_k * dot(psi_k, phi_k), g_k * dot(psi_k, phi_r)],
            [g_r * dot(phi_r, phi_k), g_r * dot(phi_r, phi_r)],
        ];
        let rhs = [g_k * dot(psi_k, e), g_r * dot(phi_r, e)];
        let one = T::one();
        let det = (one + m[0][0]) * (one + m[1][1]) - m[0][1] * m[1][0];
        if !(det.is_finite() && det > T::zero()) {
            return Err(Fault::Singular { sample: self.n, det });
        }
        let dk = (rhs[0] * (one + m[1][1]) - m[0][1] * rhs[1]) / det;
        let dr = ((one + m[0][0]) * rhs[1] - m[1][0] * rhs[0]) / det;
        Ok((dk, dr))
    }
}
