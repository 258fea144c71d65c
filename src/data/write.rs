//! Writing files without ever leaving a partial one: a temporary file in the target's
//! folder, flushed and synced, then renamed over the target (atomic on POSIX), so a reader
//! or a concurrent run never sees half a file and a failure leaves any existing file intact.

use super::experiment::Experiment;
use crate::error::Result;
use std::io::Write;
use std::path::Path;

/// Writes what `fill` writes to `path`, atomically (a [`super::staged::Staged`] of one
/// file: a temporary beside it, flushed and synced, then renamed over it).
///
/// # Errors
/// [`crate::Error::Write`] with the path when the temporary file cannot be created, written,
/// synced or renamed (the temporary file is then removed).
pub fn write_atomic(path: &Path, fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<()> {
    let mut staged = super::staged::Staged::new();
    staged.write(path, fill)?;
    staged.commit()
}

/// Writes `e` as CSV to `path`, atomically: a time column `time` \[s\] (`t_k = k h`) and then
/// every channel in order, headers the channel names, values in shortest round-trip form
/// (read back bit for bit). Gzip-compressed when the path ends in `.gz`.
///
/// # Errors
/// Those of [`write_atomic`].
pub fn write_csv(path: &Path, e: &Experiment, time: &str) -> Result<()> {
    let gz = path.extension().is_some_and(|x| x == "gz");
    write_atomic(path, |w| {
        if gz {
            let mut z = flate2::write::GzEncoder::new(w, flate2::Compression::default());
            rows(&mut z, e, time)?;
            z.finish()?;
            Ok(())
        } else {
            rows(w, e, time)
        }
    })
}

fn rows(w: &mut dyn Write, e: &Experiment, time: &str) -> std::io::Result<()> {
    let mut out = ::csv::Writer::from_writer(w);
    let header = std::iter::once(time).chain(e.channels().iter().map(|c| c.name.as_str()));
    out.write_record(header)?;
    let mut buf = Vec::with_capacity(e.channels().len() + 1);
    for k in 0..e.len() {
        buf.clear();
        buf.push(shortest(k as f64 * e.h()));
        buf.extend(e.channels().iter().map(|c| shortest(c.values[k])));
        out.write_record(&buf)?;
    }
    out.flush()
}

/// `v` as text for a CSV cell, in its shortest round-trip form: positional (`0.0001`,
/// `538.88`) for magnitudes in \[1e-5, 1e16) and zero, else in exponent form
/// (`6.828872080095706e-29`), which Rust's `Display` would write as 29 zeros and the
/// digits. Both forms read back bit for bit; `NaN`/`inf` as Rust writes them. Never fails.
pub fn shortest(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() || (1e-5..1e16).contains(&a) { format!("{v}") } else { format!("{v:e}") }
}

#[cfg(test)]
mod tests {
    use super::shortest;

    #[test]
    fn round_trips_bit_for_bit_and_stays_short() {
        for v in [
            0.0,
            -0.0,
            1e-5,
            9.99e-6,
            6.828872080095706e-29,
            -5.395937824640298e-13,
            538.888,
            1e16,
            1e300,
            5e-324,
        ] {
            let s = shortest(v);
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), v.to_bits(), "{v}: {s}");
            assert!(s.len() <= 24, "{v}: {s}");
        }
        assert_eq!(shortest(6.828872080095706e-29), "6.828872080095706e-29");
        assert_eq!(shortest(0.0001), "0.0001");
    }
}
