//! Column mistakes named from the voltage equations: d and q swapped, voltages and currents
//! swapped, the speed of the other sign, in rpm, or electrical (without `theta_m`, whose
//! speed check in [`crate::pmsm::checks::detect`] names these when it is logged).
//!
//! Each hypothesis is a least-squares regression of the voltage equations (thesis 5.2.1)
//! on the log as the mistake would have it: the speed's scale `c` enters only through
//! `ω_e = n_p c ω_m` in the rotation terms (its effect on the back-EMF term is absorbed by
//! `k_e`, which becomes `k_e / c`), so one Gram matrix of the scan gives every speed
//! hypothesis exactly; swapped columns need their own Gram, summed in the same pass over the
//! filtered signals ([`scan`]). A hypothesis is named when its
//! regression leaves [`COLUMN_RATIO`] times less of the voltage unexplained (relative to
//! the voltage's own energy) with a physical estimate (`R_s`, `L`, `k_e` > 0), and, after
//! a fit, when the prediction-error fit of the corrected log confirms it with a loss that
//! much lower (the regression alone is fooled by current noise in `di/dt`).

use crate::data::{Channel, Experiment};
use crate::error::Result;
use crate::estimate::Warning;
use crate::pmsm::checks::detect::loss_at_factor;
use crate::pmsm::checks::scan::{BASE, IDENTITY, scan_grams};
use crate::pmsm::log::signals::{DqView, channel};
use crate::pmsm::model::interval::VoltageInput;
use crate::pmsm::model::kind::MotorKind;
use crate::pmsm::options::{PmsmFitOptions, RefitReport, confirmed};
use crate::report::eng::format_eng;
use nalgebra::{DMatrix, DVector};

/// Factor by which a hypothesis must lower the unexplained share of the voltage (and,
/// after a fit, the loss) to be named.
pub const COLUMN_RATIO: f64 = 10.0;

/// The swapped columns tried (the terminal voltage only), each with the scan's lanes
/// `[u_d, u_q, i_d, i_q]` of the log as its fix reads it ([`Mistake::undo`]): d and q
/// swapped reads `[u_q, u_d, i_q, i_d]`, voltages and currents `[i_d, i_q, u_d, u_q]`.
const SWAPS: [(Mistake, [usize; 4]); 2] = [(Mistake::SwapDq, [1, 0, 3, 2]), (Mistake::SwapUi, [2, 3, 0, 1])];

/// The swaps tried only when the least-squares start fails ([`start_failure`]; their Grams
/// are summed then): the d and q currents swapped alone, `[u_d, u_q, i_q, i_d]`, or the
/// voltages alone, `[u_q, u_d, i_d, i_q]` (a negative `r_s` at the start either way).
const START_SWAPS: [(Mistake, [usize; 4]); 2] =
    [(Mistake::SwapCurrents, [0, 1, 3, 2]), (Mistake::SwapVoltages, [1, 0, 2, 3])];

/// The setup scan's Grams: the log as given ([`crate::pmsm::checks::detect`]) and, for
/// the terminal voltage, the log as each swap of columns would have it.
#[derive(Clone, Debug)]
pub(crate) struct ColumnScan {
    /// The Gram of the log as given.
    pub gram: DMatrix<f64>,
    /// The Grams of the swapped hypotheses (empty for a reference voltage).
    swapped: Vec<(Mistake, DMatrix<f64>)>,
}

/// The setup scan of the logs `views` with the voltage `input`: the Gram of the logs as given
/// and of their swapped columns, from one filtering of each log
/// ([`crate::pmsm::checks::scan::scan_grams`]).
///
/// # Errors
/// Those of [`crate::pmsm::checks::scan::scan_gram`].
pub(crate) fn scan(views: &[DqView<'_>], input: VoltageInput) -> Result<ColumnScan> {
    let swaps: &[(Mistake, [usize; 4])] = if input == VoltageInput::Terminal { &SWAPS } else { &[] };
    let lanes: Vec<[usize; 4]> = std::iter::once(IDENTITY).chain(swaps.iter().map(|s| s.1)).collect();
    let mut grams = scan_grams(views, input, &lanes)?;
    let swapped = swaps.iter().map(|s| s.0).zip(grams.drain(1..)).collect();
    Ok(ColumnScan { gram: grams.swap_remove(0), swapped })
}

/// A column mistake: what it is, the fix, and how to undo it on a log.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mistake {
    /// The speed column is `1/c` times the mechanical speed in rad/s.
    Speed(f64, &'static str, &'static str),
    /// d and q columns swapped (voltages and currents).
    SwapDq,
    /// Voltage and current columns swapped.
    SwapUi,
    /// The d and q currents swapped (the voltages right).
    SwapCurrents,
    /// The d and q voltages swapped (the currents right).
    SwapVoltages,
}

impl Mistake {
    fn what(self) -> (&'static str, &'static str) {
        match self {
            Self::Speed(_, what, fix) => (what, fix),
            Self::SwapDq => (
                "the d and q columns are swapped",
                "--col-id iq --col-iq id --col-ud uq --col-uq ud (with the log's own names)",
            ),
            Self::SwapUi => (
                "the voltage and current columns are swapped",
                "--col-ud id --col-uq iq --col-id ud --col-iq uq (with the log's own names)",
            ),
            Self::SwapCurrents => {
                ("the d and q currents are swapped", "--col-id iq --col-iq id (with the log's own names)")
            }
            Self::SwapVoltages => {
                ("the d and q voltages are swapped", "--col-ud uq --col-uq ud (with the log's own names)")
            }
        }
    }

    /// The log as the fix reads it.
    fn undo(self, e: &Experiment) -> Result<Experiment> {
        let unit = |name: &str| e.get(name).map(|c| c.unit.clone()).unwrap_or_default();
        let renamed = |from: &str, to: &str| -> Result<Channel> {
            // The values shared, not copied.
            Ok(Channel { name: to.into(), unit: unit(from), values: e.values(from)?.clone() })
        };
        let pairs: &[(&str, &str)] = match self {
            Self::Speed(c, ..) => {
                let values = e.values(channel::W_M)?.iter().map(|v| v * c).collect();
                return e.clone().with_channel(Channel::new(channel::W_M, unit(channel::W_M), values));
            }
            Self::SwapDq => &[
                (channel::I_D, channel::I_Q),
                (channel::I_Q, channel::I_D),
                (channel::U_D, channel::U_Q),
                (channel::U_Q, channel::U_D),
            ],
            Self::SwapUi => &[
                (channel::I_D, channel::U_D),
                (channel::I_Q, channel::U_Q),
                (channel::U_D, channel::I_D),
                (channel::U_Q, channel::I_Q),
            ],
            Self::SwapCurrents => &[(channel::I_D, channel::I_Q), (channel::I_Q, channel::I_D)],
            Self::SwapVoltages => &[(channel::U_D, channel::U_Q), (channel::U_Q, channel::U_D)],
        };
        let mut out = e.clone();
        let channels = pairs.iter().map(|(from, to)| renamed(from, to)).collect::<Result<Vec<_>>>()?;
        for c in channels {
            out = out.with_channel(c)?;
        }
        Ok(out)
    }
}

/// The speed hypotheses for `n_p` pole pairs: `(c, what, fix)` with `c` the factor that
/// turns the logged speed into the mechanical speed in rad/s.
fn speed_mistakes(n_p: u32) -> Vec<Mistake> {
    let (np, rpm) = (f64::from(n_p), std::f64::consts::PI / 30.0);
    let mut out =
        vec![Mistake::Speed(-1.0, "the speed has the other sign than the dq frame turns", "--negate-speed")];
    if n_p > 1 {
        out.push(Mistake::Speed(1.0 / np, "the speed is electrical", "--speed-frame electrical"));
        out.push(Mistake::Speed(
            rpm / np,
            "the speed is electrical and in rpm",
            "--speed-frame electrical --speed-unit rpm",
        ));
    }
    out.push(Mistake::Speed(rpm, "the speed is in rpm", "--speed-unit rpm"));
    out
}

/// Relative unexplained share of the voltage `loss / (½ Σu²)` and the estimate of a scan
/// Gram at the rotation factor `np`; `k_e` divided by `c`.
fn regression(g: &DMatrix<f64>, kind: MotorKind, np: f64, c: f64) -> Option<(f64, DVector<f64>)> {
    let (loss, mut theta) = loss_at_factor(g, kind, np)?;
    let energy = 0.5 * g[(BASE, BASE)];
    let last = theta.len() - 1;
    theta[last] /= c;
    (energy > 0.0).then_some((loss / energy, theta))
}

fn physical(theta: &DVector<f64>) -> bool {
    theta.iter().all(|v| *v > 0.0)
}

/// A named mistake: the mistake, the unexplained share of the voltage as given and with
/// the mistake undone, and the regression's estimate then.
struct Hypothesis {
    mistake: Mistake,
    given: f64,
    loss: f64,
    theta: DVector<f64>,
}

impl Hypothesis {
    /// The mistake, its regression's estimate and how much better it explains the voltage.
    fn describe(&self, kind: MotorKind) -> String {
        let values: Vec<String> = kind
            .table()
            .iter()
            .zip(self.theta.iter())
            .map(|(p, v)| format!("{} {}", p.name, format_eng(*v, p.unit, 4)))
            .collect();
        format!(
            "{}: the voltage equations fit {:.0} times better that way ({})",
            self.mistake.what().0,
            self.given / self.loss,
            values.join(", ")
        )
    }
}

/// The mistake whose regression explains the voltage [`COLUMN_RATIO`] times better than
/// the log as given, with a physical estimate; `scan` the setup scan's Grams, `more` the
/// Grams of further swaps. Swapped columns are tried for the terminal voltage only.
fn best_hypothesis(
    scan: &ColumnScan,
    more: &[(Mistake, DMatrix<f64>)],
    options: &PmsmFitOptions,
) -> Option<Hypothesis> {
    let (n_p, kind) = (options.pole_pairs, options.model);
    let np = f64::from(n_p);
    let (given, _) = regression(&scan.gram, kind, np, 1.0)?;
    let mut tried: Vec<(Mistake, f64, DVector<f64>)> = speed_mistakes(n_p)
        .into_iter()
        .filter_map(|m| {
            let Mistake::Speed(c, ..) = m else { return None };
            regression(&scan.gram, kind, np * c, c).map(|(l, t)| (m, l, t))
        })
        .collect();
    for (m, gm) in scan.swapped.iter().chain(more) {
        tried.extend(regression(gm, kind, np, 1.0).map(|(l, t)| (*m, l, t)));
    }
    tried
        .into_iter()
        .filter(|(_, l, t)| physical(t) && l * COLUMN_RATIO <= given)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(mistake, loss, theta)| Hypothesis { mistake, given, loss, theta })
}

/// Why the least-squares start failed, when a column mistake explains it: the text to add
/// to its error, naming the mistake and the fix; `None` when no hypothesis does. `scan` is
/// the setup scan of the logs `views`; the swaps of [`START_SWAPS`] are scanned here.
pub(crate) fn start_failure(
    scan: &ColumnScan,
    views: &[DqView<'_>],
    options: &PmsmFitOptions,
) -> Option<String> {
    let more: Vec<(Mistake, DMatrix<f64>)> = if options.input == VoltageInput::Terminal {
        let lanes: Vec<[usize; 4]> = START_SWAPS.iter().map(|s| s.1).collect();
        let grams = scan_grams(views, options.input, &lanes).ok()?;
        START_SWAPS.iter().map(|s| s.0).zip(grams).collect()
    } else {
        Vec::new()
    };
    let h = best_hypothesis(scan, &more, options)?;
    Some(format!("{}; read the log with {}", h.describe(options.model), h.mistake.what().1))
}

/// After a fit of loss `loss`: an untrusted `columns` warning when a column mistake
/// explains the log [`COLUMN_RATIO`] times better by regression and the fit of the
/// corrected log confirms it.
pub(crate) fn warning(
    scan: &ColumnScan,
    experiments: &[Experiment],
    options: &PmsmFitOptions,
    loss: f64,
    refit: RefitReport<'_>,
) -> Option<Warning> {
    let kind = options.model;
    let h = best_hypothesis(scan, &[], options)?;
    let undone: Vec<Experiment> =
        experiments.iter().map(|e| h.mistake.undo(e)).collect::<Result<_>>().ok()?;
    let times = confirmed(refit, &undone, options.clone(), loss, COLUMN_RATIO)?;
    Some(Warning::untrusted(
        "columns",
        format!(
            "{}, and the fit of the log read so has a {:.0} times lower loss; read the log with {}",
            h.describe(kind),
            times,
            h.mistake.what().1
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::{DriveConfig, SPM_MOTOR, scenario, simulate_drive};
    use crate::pmsm::checks::scan::{CROSS, GRAM, scan_gram};

    /// The swapped hypotheses' Grams from the one pass are those of a scan of the log as each
    /// fix reads it, to the bit (over several of the scan's chunks), but for the cross
    /// columns, which only the logs as given sum (zero in the swapped ones).
    #[test]
    fn the_swapped_grams_are_the_swapped_logs_scans() {
        let cfg = DriveConfig { duration: 0.9, ..scenario("exp3", SPM_MOTOR).unwrap() };
        let log = simulate_drive(&cfg).unwrap().experiment;
        let logs = [log.clone(), log.slice(100..5000).unwrap()];
        fn views(logs: &[Experiment]) -> Vec<DqView<'_>> {
            logs.iter().map(|e| DqView::try_new(e).unwrap()).collect()
        }
        let scan = scan(&views(&logs), VoltageInput::Terminal).unwrap();
        let bits = |g: &DMatrix<f64>| g.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let plain = |g: &DMatrix<f64>| bits(&g.view((0, 0), (GRAM - CROSS, GRAM - CROSS)).into_owned());
        assert_eq!(bits(&scan.gram), bits(&scan_gram(&views(&logs), VoltageInput::Terminal).unwrap()));
        assert_eq!(scan.swapped.len(), SWAPS.len());
        for (m, g) in &scan.swapped {
            let undone: Vec<Experiment> = logs.iter().map(|e| m.undo(e).unwrap()).collect();
            assert_eq!(
                plain(g),
                plain(&scan_gram(&views(&undone), VoltageInput::Terminal).unwrap()),
                "{m:?}"
            );
            assert!(g.view((0, GRAM - CROSS), (GRAM, CROSS)).iter().all(|x| *x == 0.0), "{m:?}");
            assert_ne!(plain(g), plain(&scan.gram), "{m:?}");
        }
    }
}
