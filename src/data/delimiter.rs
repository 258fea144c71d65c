//! The field delimiter of a CSV log: comma (default), semicolon, tab or pipe.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The byte that separates the fields of a CSV log: `,` (default), `;` (European CSV,
/// where `,` is the decimal mark of spreadsheets), tab or `|`.
///
/// Other bytes are refused: `"` quotes and line breaks end records, so neither can
/// separate fields; letters, digits, `.`, `+` and `-` belong to numbers; a space cannot
/// either, since fields are trimmed of blanks and whitespace-aligned columns hold runs of
/// spaces (convert such a file to one of the four first). Written and parsed as `,` `;`
/// `tab` `|` ([`FromStr`] also takes `comma`, `semicolon`, `pipe`, `\t` and a literal tab),
/// so a JSON option file holds `"delimiter": ";"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct Delimiter(u8);

impl Delimiter {
    /// `,`, the default.
    pub const COMMA: Self = Self(b',');
    /// `;`.
    pub const SEMICOLON: Self = Self(b';');
    /// Tab (`\t`).
    pub const TAB: Self = Self(b'\t');
    /// `|`.
    pub const PIPE: Self = Self(b'|');

    /// The four delimiters, in the order the errors list them.
    pub const ALL: [Self; 4] = [Self::COMMA, Self::SEMICOLON, Self::TAB, Self::PIPE];

    /// The delimiter `byte` (one of `,` `;` `\t` `|`).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming `delimiter` for any other byte.
    pub fn new(byte: u8) -> Result<Self> {
        Self::ALL.into_iter().find(|d| d.0 == byte).ok_or_else(|| invalid(&String::from_utf8_lossy(&[byte])))
    }

    /// The byte itself.
    pub fn byte(self) -> u8 {
        self.0
    }

    /// How a user writes it: `,` `;` `tab` `|`.
    pub fn name(self) -> &'static str {
        match self.0 {
            b';' => ";",
            b'\t' => "tab",
            b'|' => "|",
            _ => ",",
        }
    }
}

impl Default for Delimiter {
    fn default() -> Self {
        Self::COMMA
    }
}

impl fmt::Display for Delimiter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Delimiter {
    type Err = Error;

    /// `,` `;` `tab` `|` (or `comma`, `semicolon`, `\t`, a literal tab, `pipe`; names in
    /// any case).
    ///
    /// # Errors
    /// [`Error::InvalidOption`] naming `delimiter` and listing the accepted values for
    /// anything else (a multi-character text, a non-ASCII character, `"`, a line break, a
    /// space, …).
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "," | "comma" => Ok(Self::COMMA),
            ";" | "semicolon" => Ok(Self::SEMICOLON),
            "\t" | "\\t" | "tab" => Ok(Self::TAB),
            "|" | "pipe" => Ok(Self::PIPE),
            _ => Err(invalid(s)),
        }
    }
}

impl TryFrom<String> for Delimiter {
    type Error = Error;

    fn try_from(s: String) -> Result<Self> {
        s.parse()
    }
}

impl From<Delimiter> for String {
    fn from(d: Delimiter) -> Self {
        d.name().to_string()
    }
}

fn invalid(s: &str) -> Error {
    let why = match s {
        "\"" => "`\"` quotes fields",
        "\n" | "\r" | "\r\n" => "a line break ends records",
        " " | "space" => "fields are trimmed of blanks, so a space cannot separate them",
        _ if s.chars().count() > 1 => "one character is expected",
        _ if !s.is_ascii() => "one ASCII character is expected",
        _ => "not a field delimiter the reader takes",
    };
    Error::InvalidOption {
        option: "delimiter".into(),
        reason: format!("{:?}: {why}; use one of `,` `;` `tab` `|`", s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_and_print_back() {
        for (s, d) in [(",", b','), (";", b';'), ("tab", b'\t'), ("\\t", b'\t'), ("\t", b'\t'), ("|", b'|')] {
            let parsed: Delimiter = s.parse().unwrap();
            assert_eq!(parsed.byte(), d, "{s:?}");
            assert_eq!(parsed.to_string().parse::<Delimiter>().unwrap(), parsed);
            assert_eq!(Delimiter::new(d).unwrap(), parsed);
        }
        assert_eq!(Delimiter::default(), Delimiter::COMMA);
        let json = serde_json::to_string(&Delimiter::TAB).unwrap();
        assert_eq!(json, "\"tab\"");
        assert_eq!(serde_json::from_str::<Delimiter>(&json).unwrap(), Delimiter::TAB);
        assert!(serde_json::from_str::<Delimiter>("\"ab\"").is_err());
    }

    #[test]
    fn bad_delimiters_are_refused_naming_the_option() {
        for s in ["", ";;", "ab", "é", "\"", "\n", " ", "space", ".", "1", "\\n"] {
            let e = s.parse::<Delimiter>().unwrap_err().to_string();
            assert!(e.contains("`delimiter`") && e.contains("`;`"), "{s:?}: {e}");
        }
        assert!(Delimiter::new(b'"').is_err());
        assert!(Delimiter::new(b'\n').is_err());
        assert!(Delimiter::new(0xe9).is_err());
    }
}
