//! Standard columns found under other names: a log's header entry that looks like a
//! missing standard column (`Id` for `id`, `speed_rpm` for `w_m`), and the speed unit a
//! column's name states, so that a front end can name every renamed column in one
//! message, in its own words (the command line's `--col-id "Id"`, Python's `col_id="Id"`).

use crate::pmsm::SpeedUnit;

/// Other names logs give the standard columns (compared without case, units in brackets
/// or punctuation).
const COLUMN_ALIASES: [(&str, &[&str]); 7] = [
    ("t", &["time", "times", "timestamp", "ts"]),
    ("ud", &["vd", "voltaged", "udmeas"]),
    ("uq", &["vq", "voltageq", "uqmeas"]),
    ("id", &["currentd", "idmeas"]),
    ("iq", &["currentq", "iqmeas"]),
    ("w_m", &["wm", "w", "omega", "omegam", "speed", "velocity"]),
    ("theta_m", &["thetam", "theta", "angle", "position", "pos"]),
];

/// Units a speed column's name may end in, and the speed unit each says.
const SPEED_UNIT_SUFFIXES: [(&str, SpeedUnit); 3] =
    [("rpm", SpeedUnit::Rpm), ("rads", SpeedUnit::RadPerSec), ("radpers", SpeedUnit::RadPerSec)];

/// The standard columns a fit reads under a name of the user's choice, in the order the
/// options list them, with the option that renames each (`col_w` for `w_m`).
pub const RENAMEABLE: [(&str, &str); 9] = [
    ("t", "col_t"),
    ("ud", "col_ud"),
    ("uq", "col_uq"),
    ("id", "col_id"),
    ("iq", "col_iq"),
    ("w_m", "col_w"),
    ("theta_m", "col_theta"),
    ("ud_ref", "col_ud_ref"),
    ("uq_ref", "col_uq_ref"),
];

/// A header name without case, units in brackets or parentheses, and punctuation.
fn normalised(name: &str) -> String {
    let mut depth = 0i32;
    name.chars()
        .filter(|c| {
            match c {
                '[' | '(' => depth += 1,
                ']' | ')' => depth -= 1,
                _ => return depth == 0 && c.is_alphanumeric(),
            }
            false
        })
        .flat_map(char::to_lowercase)
        .collect()
}

/// The entry of `available` (a header's names joined by `", "`) that looks like the
/// standard column `column`: the same name without case and punctuation, a common alias,
/// or either with a unit at its end (`speed_rpm`).
pub fn look_alike<'a>(column: &str, available: &'a str) -> Option<&'a str> {
    let names: Vec<String> = std::iter::once(normalised(column))
        .chain(
            COLUMN_ALIASES
                .iter()
                .filter(|(c, _)| *c == column)
                .flat_map(|(_, a)| a.iter().map(|s| s.to_string())),
        )
        .collect();
    // A name that ends in a unit (`speed_rpm`) is the column without it.
    let bare = |h: &str| {
        let n = normalised(h);
        SPEED_UNIT_SUFFIXES.iter().find_map(|(s, _)| n.strip_suffix(s).map(str::to_string)).unwrap_or(n)
    };
    available.split(", ").find(|h| names.contains(&normalised(h)) || names.contains(&bare(h)))
}

/// The speed unit the header's speed column states in its name (`speed_rpm`: rpm), when
/// it is not the default rad/s.
pub fn speed_unit_in_header(available: &str) -> Option<SpeedUnit> {
    available.split(", ").find_map(|h| {
        let n = normalised(h);
        SPEED_UNIT_SUFFIXES.iter().find_map(|(suffix, unit)| {
            let stem = n.strip_suffix(suffix)?;
            let speed = COLUMN_ALIASES.iter().find(|(c, _)| *c == "w_m")?.1.contains(&stem);
            (speed && *unit != SpeedUnit::RadPerSec).then_some(*unit)
        })
    })
}

/// Every column of [`RENAMEABLE`] absent from `available` whose look-alike is there:
/// (standard name, option, header name), in the options' order.
pub fn renamed_columns(available: &str) -> Vec<(&'static str, &'static str, String)> {
    RENAMEABLE
        .iter()
        .filter(|(standard, _)| !available.split(", ").any(|h| h == *standard))
        .filter_map(|(standard, option)| {
            Some((*standard, *option, look_alike(standard, available)?.to_string()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renamed_columns_and_the_unit_in_a_name_are_found() {
        let header = "t, Id, Iq, Ud, Uq, speed_rpm";
        let found: Vec<(&str, String)> =
            renamed_columns(header).into_iter().map(|(s, _, h)| (s, h)).collect();
        let expect = [("ud", "Ud"), ("uq", "Uq"), ("id", "Id"), ("iq", "Iq"), ("w_m", "speed_rpm")];
        assert_eq!(found, expect.map(|(s, h)| (s, h.to_string())));
        assert_eq!(speed_unit_in_header(header), Some(SpeedUnit::Rpm));
        assert_eq!(speed_unit_in_header("t, omega [rad/s]"), None);
        assert_eq!(look_alike("t", "Time [s], x"), Some("Time [s]"));
        assert_eq!(look_alike("iq", "a, b"), None);
    }
}
