//! The residual export: measured, simulated and residual outputs of each log as CSV, so
//! that any tool can plot them.

use super::Comparison;
use crate::data::{shortest, write_atomic};
use crate::error::{Error, Result};
use std::path::Path;

/// Writes `comparisons` to `path` as CSV, atomically
/// ([`write_atomic`]): a header `t, <output>_measured, <output>_simulated,
/// <output>_residual, …` (output names as in the comparisons, e.g. `id_measured`), then
/// one row per sample with `t = t0 + k h` \[s\] in the log's own time and the outputs in
/// their units (SI); the residual is `measured − simulated`. With several comparisons a
/// first column `log` names each row's log and the logs follow each other in blocks. When
/// the fit weighted samples out ([`Comparison::counted`]), a last column `counted` (1 or 0)
/// says which residuals its figures count; `simulated` is the fit's k-step prediction when
/// it had a horizon ([`Comparison::horizon`]).
/// Numbers are in shortest round-trip form (read back bit for bit).
///
/// # Errors
/// [`Error::InvalidOption`] (option `residuals`) for no comparison or comparisons with
/// different outputs; [`Error::Write`] naming the path when it cannot be written (no
/// partial or temporary file is then left).
pub fn write_residuals_csv(path: &Path, comparisons: &[Comparison]) -> Result<()> {
    let bad = |reason: String| Error::InvalidOption { option: "residuals".into(), reason };
    let first = comparisons.first().ok_or_else(|| bad("no log to export".into()))?;
    if let Some(c) = comparisons.iter().find(|c| c.outputs != first.outputs) {
        return Err(bad(format!("log `{}` has other outputs than `{}`", c.experiment, first.experiment)));
    }
    let several = comparisons.len() > 1;
    write_atomic(path, |w| {
        let mut out = csv::Writer::from_writer(w);
        let mut header: Vec<String> = Vec::new();
        if several {
            header.push("log".into());
        }
        header.push("t".into());
        for o in &first.outputs {
            header.extend(["measured", "simulated", "residual"].map(|s| format!("{o}_{s}")));
        }
        // Whether the fit counted each sample, when it weighted some out (their residual is
        // then no part of the fit's figures).
        let flagged = comparisons.iter().any(|c| !c.counted.is_empty());
        if flagged {
            header.push("counted".into());
        }
        out.write_record(&header)?;
        let ny = first.outputs.len();
        let mut row: Vec<String> = Vec::with_capacity(header.len());
        for c in comparisons {
            for k in 0..c.len() {
                row.clear();
                if several {
                    row.push(c.experiment.clone());
                }
                row.push(shortest(c.t0 + k as f64 * c.h));
                for i in 0..ny {
                    let (y, y_hat) = (c.y[k * ny + i], c.y_hat[k * ny + i]);
                    row.extend([shortest(y), shortest(y_hat), shortest(y - y_hat)]);
                }
                if flagged {
                    row.push(u8::from(c.counts(k)).to_string());
                }
                out.write_record(&row)?;
            }
        }
        out.flush()?;
        Ok(())
    })
}
