//! The 18 nonlinear least-squares problems of MINPACK's `lmder` test driver (Moré, Garbow
//! & Hillstrom, "Testing unconstrained optimization software", *ACM TOMS* 7 (1981) 17–41),
//! with the driver's 53 cases: the sizes (m, n) and starts ×1, ×10, ×100 of `ssq.data`.
//!
//! Each problem gives residuals `r(x)` (length m) and the analytic Jacobian `∂r/∂x`
//! (row-major m × n), transcribed from MINPACK-1's `ssqfcn.f`, `ssqjac.f` and `ssqipt.f`
//! (Argonne, March 1980; as distributed with cminpack, `examples/`). The start ×f is
//! `f x₀`, except Watson, whose standard start is 0: there every component is f.
//!
//! Reference figures per case ([`Case`]):
//! - `published`: the final `‖r‖` of MINPACK's reference output of `lmddrv` (cminpack
//!   `examples/ref/lmddrv.ref`, 7 significant digits), with its `nfev`, `njev` and `info`;
//! - `minpack`: the same run with the same code at full precision: cminpack 1.3.14's
//!   double-precision `lmder1` (the C transcription of `lmder`) and its copy of the driver,
//!   built with `gcc -O2 -ffp-contract=off` on x86-64, printing 17 digits. Its `nfev`,
//!   `njev` and `info` equal the published ones in all 53 cases and its norms agree to
//!   the 7 printed digits, except Brown almost-linear ×100 (zero residual: 8.4e-15 against
//!   5.3e-15, rounding noise);
//! - `initial`: `‖r(x₀)‖` of that run, a check of the residuals transcribed here.
//!
//! A later adapter can wrap a problem as a static grey-box model: the parameters are x, the
//! prediction is `ŷ(x) = y − r(x)` for any data y, and `∂ŷ/∂x = −∂r/∂x`.

mod classic;
mod data;
mod linear;
mod other;

pub use classic::{
    BoxThreeD, BrownDennis, FreudensteinRoth, HelicalValley, JennrichSampson, PowellSingular, Rosenbrock,
};
pub use data::{Bard, KowalikOsborne, Meyer, Osborne1, Osborne2};
pub use linear::{LinearFullRank, LinearRank1, LinearRank1ZeroColumns};
pub use other::{BrownAlmostLinear, Chebyquad, Watson};

/// A nonlinear least-squares test problem `min_x ½‖r(x)‖²`.
pub trait MghProblem: Sync {
    /// The problem's name in Moré, Garbow & Hillstrom (1981).
    fn name(&self) -> &str;
    /// Number of residuals m.
    fn m(&self) -> usize;
    /// Number of variables n.
    fn n(&self) -> usize;
    /// The standard start x₀ (length n).
    fn start(&self) -> Vec<f64>;
    /// The start of MINPACK's driver for `factor` = 1, 10, 100: `factor x₀`.
    fn start_at(&self, factor: f64) -> Vec<f64> {
        self.start().iter().map(|x| factor * x).collect()
    }
    /// Residuals r(x), length m.
    fn residuals(&self, x: &[f64], r: &mut [f64]);
    /// Jacobian `∂r_i/∂x_k` at `j[i n + k]` (row-major m × n).
    fn jacobian(&self, x: &[f64], j: &mut [f64]);
}

/// One run of MINPACK's driver: a problem, a start and MINPACK's figures.
pub struct Case {
    /// MINPACK's problem number (1–18, `ssqfcn.f`).
    pub nprob: usize,
    /// The problem.
    pub problem: Box<dyn MghProblem>,
    /// Start factor: 1, 10 or 100.
    pub factor: f64,
    /// `‖r(x₀)‖` at the start of the full-precision run.
    pub initial: f64,
    /// Final `‖r‖`, full precision (cminpack's `lmder1`).
    pub minpack: f64,
    /// Final `‖r‖` as published (7 significant digits).
    pub published: f64,
    /// MINPACK's function evaluations.
    pub nfev: u32,
    /// MINPACK's Jacobian evaluations.
    pub njev: u32,
    /// MINPACK's exit parameter `info` (1–4 converged, 5 `maxfev` reached).
    pub info: u32,
}

impl Case {
    /// Whether MINPACK reports convergence (`info` 1–4).
    pub fn minpack_converged(&self) -> bool {
        (1..=4).contains(&self.info)
    }
}

/// The problem `nprob` of `ssqfcn.f` with n variables and m residuals.
pub fn problem(nprob: usize, n: usize, m: usize) -> Box<dyn MghProblem> {
    match nprob {
        1 => Box::new(LinearFullRank { n, m }),
        2 => Box::new(LinearRank1 { n, m }),
        3 => Box::new(LinearRank1ZeroColumns { n, m }),
        4 => Box::new(Rosenbrock),
        5 => Box::new(HelicalValley),
        6 => Box::new(PowellSingular),
        7 => Box::new(FreudensteinRoth),
        8 => Box::new(Bard),
        9 => Box::new(KowalikOsborne),
        10 => Box::new(Meyer),
        11 => Box::new(Watson { n }),
        12 => Box::new(BoxThreeD { m }),
        13 => Box::new(JennrichSampson { m }),
        14 => Box::new(BrownDennis { m }),
        15 => Box::new(Chebyquad { n, m }),
        16 => Box::new(BrownAlmostLinear { n }),
        17 => Box::new(Osborne1),
        18 => Box::new(Osborne2),
        _ => panic!("MINPACK has problems 1 to 18, not {nprob}"),
    }
}

/// `(nprob, n, m, factor, initial ‖r‖, final ‖r‖ full precision, final ‖r‖ published,
/// nfev, njev, info)`.
type Row = (usize, usize, usize, f64, f64, f64, f64, u32, u32, u32);

#[rustfmt::skip]
const ROWS: [Row; 53] = [
    (1, 5, 10, 1.0, 5.0, 2.23606797749979, 2.236068, 3, 2, 3),
    (1, 5, 50, 1.0, 8.062257748298547, 6.708203932499369, 6.708204, 3, 2, 3),
    (2, 5, 10, 1.0, 291.52186881947637, 1.4638501094227998, 1.46385, 3, 2, 1),
    (2, 5, 50, 1.0, 3101.6003933453453, 3.4826301657349625, 3.48263, 3, 2, 1),
    (3, 5, 10, 1.0, 126.03967629282455, 1.9097274212644622, 1.909727, 3, 2, 1),
    (3, 5, 50, 1.0, 1748.9499706967035, 3.6917294022424563, 3.691729, 3, 2, 1),
    (4, 2, 2, 1.0, 4.919349550499537, 0.0, 0.0, 21, 16, 4),
    (4, 2, 2, 10.0, 1340.063058217784, 0.0, 0.0, 8, 5, 2),
    (4, 2, 2, 100.0, 143000.05119229853, 0.0, 0.0, 6, 4, 2),
    (5, 3, 3, 1.0, 50.0, 9.936523103425631e-17, 9.936523e-17, 11, 8, 2),
    (5, 3, 3, 10.0, 102.95630140987001, 1.0446788506548094e-19, 1.044679e-19, 20, 15, 2),
    (5, 3, 3, 100.0, 991.2618221237011, 3.1387778119467796e-29, 3.138778e-29, 19, 16, 2),
    (6, 4, 4, 1.0, 14.662878298615182, 6.109327859207778e-34, 6.109328e-34, 59, 58, 4),
    (6, 4, 4, 10.0, 1270.9838708654017, 9.103607921611894e-40, 9.103608e-40, 72, 71, 4),
    (6, 4, 4, 100.0, 126887.90328474973, 2.330523627932644e-35, 2.330524e-35, 68, 67, 4),
    (7, 2, 2, 1.0, 20.0124960961895, 6.998875175845752, 6.998875, 14, 8, 1),
    (7, 2, 2, 10.0, 12432.833948862986, 6.9988751744895055, 6.998875, 19, 12, 1),
    (7, 2, 2, 100.0, 11426454.595761977, 6.998875172429027, 6.998875, 24, 17, 1),
    (8, 3, 15, 1.0, 6.456136295159668, 0.09063596033904667, 0.09063596, 6, 5, 1),
    (8, 3, 15, 10.0, 36.141853159678455, 4.174768701385386, 4.174769, 37, 36, 1),
    (8, 3, 15, 100.0, 384.11467863739915, 4.1747687013596915, 4.174769, 14, 13, 1),
    (9, 4, 11, 1.0, 0.07289151028829448, 0.017535837721128954, 0.01753584, 18, 16, 1),
    (9, 4, 11, 10.0, 2.9793700755520205, 0.032052192917936956, 0.03205219, 78, 70, 1),
    (9, 4, 11, 100.0, 29.959061701603652, 0.01753583967605901, 0.01753584, 500, 380, 5),
    (10, 3, 16, 1.0, 41153.46655430312, 9.377945146497645, 9.377945, 126, 116, 2),
    (10, 3, 16, 10.0, 4168216.8913084646, 799.4074042933858, 799.4077, 400, 345, 5),
    (11, 6, 31, 1.0, 5.477225575051661, 0.047829593909760784, 0.04782959, 8, 7, 1),
    (11, 6, 31, 10.0, 6433.125789500264, 0.047829593909695066, 0.04782959, 14, 13, 1),
    (11, 6, 31, 100.0, 674256.0406052133, 0.04782959391154404, 0.04782959, 15, 14, 1),
    (11, 9, 31, 1.0, 5.477225575051661, 0.0011831145921245528, 0.001183115, 8, 7, 3),
    (11, 9, 31, 10.0, 12088.127069307002, 0.0011831145921246938, 0.001183115, 19, 15, 1),
    (11, 9, 31, 100.0, 1269109.2904383382, 0.0011831145921243115, 0.001183115, 19, 16, 3),
    (11, 12, 31, 1.0, 5.477225575051661, 2.1731040254851155e-05, 2.173104e-05, 10, 9, 3),
    (11, 12, 31, 10.0, 19220.758979095073, 2.173104025099853e-05, 2.173104e-05, 13, 12, 3),
    (11, 12, 31, 100.0, 2018918.0446236664, 2.1731040254487666e-05, 2.173104e-05, 34, 28, 2),
    (12, 3, 10, 1.0, 32.11158374495718, 2.4196749845665633e-16, 2.419675e-16, 7, 6, 2),
    (13, 2, 10, 1.0, 64.58564981449433, 11.151779341349885, 11.15178, 21, 12, 1),
    (14, 4, 20, 1.0, 2815.4383916181564, 292.9542881912278, 292.9543, 254, 236, 1),
    (14, 4, 20, 10.0, 555073.3541730687, 292.95427058141513, 292.9543, 53, 42, 1),
    (14, 4, 20, 100.0, 61211252.23385811, 292.95430615446, 292.9543, 237, 221, 1),
    (15, 1, 8, 1.0, 1.886237969077315, 1.886237969077315, 1.886238, 1, 1, 4),
    (15, 1, 8, 10.0, 5383344372.340053, 1.8842482049995073, 1.884248, 29, 28, 1),
    (15, 1, 8, 100.0, 1.1808872669839173e+18, 1.8842482049934663, 1.884248, 47, 46, 1),
    (15, 8, 8, 1.0, 0.1965138628339747, 0.05930323550467261, 0.05930324, 39, 20, 1),
    (15, 9, 9, 1.0, 0.16994993465202024, 1.7600835153242613e-16, 1.760084e-16, 12, 9, 2),
    (15, 10, 10, 1.0, 0.18374783117871077, 0.08064710040382533, 0.0806471, 25, 12, 1),
    (16, 10, 10, 1.0, 16.530216206349944, 8.662585850030506e-15, 8.662586e-15, 14, 12, 2),
    (16, 10, 10, 10.0, 9765624.000892108, 5.0009355010672645e-15, 5.000936e-15, 13, 8, 2),
    (16, 10, 10, 100.0, 9.765625e+16, 8.373908221563065e-15, 5.329071e-15, 22, 20, 2),
    (16, 30, 30, 1.0, 83.476044467848, 1.48278587478574e-13, 1.482786e-13, 19, 14, 2),
    (16, 40, 40, 1.0, 128.02636447232265, 2.024535445435496e-13, 2.024535e-13, 19, 14, 2),
    (17, 5, 33, 1.0, 0.9375640210378385, 0.007392492609048216, 0.007392493, 18, 15, 1),
    (18, 11, 65, 1.0, 1.4468654098471168, 0.20034404483314, 0.200344, 16, 12, 1),
];

/// The 53 cases of MINPACK's driver, in its order.
pub fn cases() -> Vec<Case> {
    ROWS.iter()
        .map(|&(nprob, n, m, factor, initial, minpack, published, nfev, njev, info)| Case {
            nprob,
            problem: problem(nprob, n, m),
            factor,
            initial,
            minpack,
            published,
            nfev,
            njev,
            info,
        })
        .collect()
}
