//! The fast CSV reader against the reader it replaced (kept here, verbatim in behaviour, as
//! the oracle): the same table or the same error message on generated files, small (one
//! chunk, where even the order of competing errors must match) and large (many chunks
//! parsed in parallel, with one fault placed anywhere); and its number parser against
//! `str::parse::<f64>` on random texts, bit for bit.

use crate::common::TempFile;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

use greybox::Error;
use greybox::data::TimeSteps;
use greybox::data::{Delimiter, ReadLimits, Table};
use proptest::prelude::*;

/// The CSV reader with the time column checked as it streams.
pub(crate) fn read_table(
    path: impl AsRef<std::path::Path>,
    wanted: &[(&str, bool)],
    limits: &ReadLimits,
    delimiter: Delimiter,
) -> greybox::Result<Table> {
    greybox::data::csv::read_table_with(path, wanted, limits, delimiter, greybox::data::TimeCheck::Streaming)
}

/// The reader as it was before the fast path (commit ad58799), errors as strings.
pub mod oracle {
    use super::*;

    struct LineLimit<R> {
        inner: R,
        max: u64,
        run: u64,
        line: u64,
        quoted: bool,
    }

    #[derive(Debug)]
    struct LineTooLong {
        line: u64,
        max: u64,
    }
    impl std::fmt::Display for LineTooLong {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "line {} is longer than {} bytes", self.line, self.max)
        }
    }
    impl std::error::Error for LineTooLong {}

    impl<R: Read> Read for LineLimit<R> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = self.inner.read(buf)?;
            let mut start = 0;
            for (i, &b) in buf[..n].iter().enumerate() {
                if b == b'"' {
                    self.quoted = !self.quoted;
                } else if matches!(b, b'\n' | b'\r') && !self.quoted {
                    self.check(i - start)?;
                    self.run = 0;
                    start = i + 1;
                }
                self.line += u64::from(b == b'\n');
            }
            self.check(n - start)?;
            Ok(n)
        }
    }
    impl<R> LineLimit<R> {
        fn check(&mut self, bytes: usize) -> std::io::Result<()> {
            self.run += bytes as u64;
            if self.run > self.max {
                return Err(std::io::Error::other(LineTooLong { line: self.line, max: self.max }));
            }
            Ok(())
        }
    }

    fn csv_error(path: &Path, e: csv::Error) -> Error {
        let line = e.position().map_or(0, |p| p.line());
        match e.into_kind() {
            csv::ErrorKind::Io(source) => {
                if let Some(long) = source.get_ref().and_then(|e| e.downcast_ref::<LineTooLong>()) {
                    return Error::LimitExceeded {
                        path: path.to_path_buf(),
                        line: long.line,
                        what: format!("a line (record) longer than {} bytes", long.max),
                        limit: "max_line_bytes".into(),
                        max: long.max,
                    };
                }
                Error::Io { path: path.to_path_buf(), source }
            }
            csv::ErrorKind::UnequalLengths { expected_len, len, .. } => Error::Csv {
                path: path.to_path_buf(),
                line,
                message: format!("row has {len} fields, the header has {expected_len}"),
            },
            other => Error::Csv { path: path.to_path_buf(), line, message: format!("{other:?}") },
        }
    }

    /// The first 80 characters of a cell, and its length in bytes when cut.
    fn excerpt(field: &[u8]) -> (String, Option<usize>) {
        let max = 320;
        let head = String::from_utf8_lossy(&field[..field.len().min(max)]);
        match head.char_indices().nth(80) {
            Some((cut, _)) => (head[..cut].to_string(), Some(field.len())),
            None if field.len() > max => (head.into_owned(), Some(field.len())),
            None => (head.into_owned(), None),
        }
    }

    fn quote(field: &[u8]) -> String {
        match excerpt(field) {
            (head, Some(len)) => format!("`{head}…` ({len} bytes)"),
            (head, None) => format!("`{head}`"),
        }
    }

    /// A header name in the list of a missing-column error: as `quote`, without backquotes.
    fn name_excerpt(field: &[u8]) -> String {
        match excerpt(field) {
            (head, Some(len)) => format!("{head}… ({len} bytes)"),
            (head, None) => head,
        }
    }

    /// The `\n` of the blank lines before the first record (after a byte order mark).
    fn blank_lines(path: &Path) -> u64 {
        let mut bytes = std::fs::read(path).unwrap();
        if bytes.starts_with(&[0x1f, 0x8b]) {
            let mut plain = Vec::new();
            flate2::read::MultiGzDecoder::new(bytes.as_slice()).read_to_end(&mut plain).unwrap();
            bytes = plain;
        }
        let text = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(&bytes);
        text.iter().take_while(|b| matches!(b, b'\n' | b'\r')).filter(|&&b| b == b'\n').count() as u64
    }

    pub fn read_table(path: &Path, wanted: &[(&str, bool)], limits: &ReadLimits) -> Result<Table, String> {
        let s = |e: Error| e.to_string();
        let name = path.file_name().unwrap().to_string_lossy().replace(".gz", "").replace(".csv", "");
        let io_err = |source| s(Error::Io { path: path.to_path_buf(), source });
        let file = std::fs::File::open(path).map_err(io_err)?;
        let mut buf = BufReader::with_capacity(1 << 16, file);
        let gz = buf.fill_buf().map_err(io_err)?.starts_with(&[0x1f, 0x8b]);
        let reader: Box<dyn Read> =
            if gz { Box::new(flate2::read::MultiGzDecoder::new(buf)) } else { Box::new(buf) };
        let limited = LineLimit { inner: reader, max: limits.max_line_bytes, run: 0, line: 1, quoted: false };
        let mut rdr =
            csv::ReaderBuilder::new().trim(csv::Trim::All).buffer_capacity(1 << 16).from_reader(limited);
        let header_record = rdr.byte_headers().map_err(|e| s(csv_error(path, e)))?;
        // The `csv` crate numbers the first record 1 even after blank lines; the reader (as
        // the fast path before it) names the header's own line.
        let header_line = header_record.position().map_or(1, csv::Position::line) + blank_lines(path);
        let header: Vec<String> =
            header_record.iter().map(|f| String::from_utf8_lossy(f).into_owned()).collect();
        let p = path.to_path_buf();
        if header.len() > limits.max_fields {
            return Err(s(Error::LimitExceeded {
                path: p,
                line: 1,
                what: format!("a header of {} fields", header.len()),
                limit: "max_fields".into(),
                max: limits.max_fields as u64,
            }));
        }
        if header.iter().all(String::is_empty) {
            return Err(s(Error::TooShort { name, len: 0, min: 1 }));
        }
        let mut index = Vec::new();
        for &(column, required) in wanted {
            let found: Vec<usize> =
                header.iter().enumerate().filter(|(_, h)| *h == column).map(|(i, _)| i).collect();
            if found.len() > 1 {
                let (first, second) = (found[0] + 1, found[1] + 1);
                return Err(s(Error::DuplicateColumn { path: p, column: column.into(), first, second }));
            }
            if found.is_empty() && required {
                // A header of one field that holds another delimiter names it (the reader's
                // hint since the delimiter option).
                if let [only] = header.as_slice()
                    && let Some(d) = Delimiter::ALL
                        .into_iter()
                        .find(|d| *d != Delimiter::COMMA && only.contains(d.byte() as char))
                {
                    let message = format!(
                        "the header is one field, {}, which holds `{}`: read the file with the delimiter `{d}` \
                         (`--delimiter '{d}'`), not `{}`",
                        quote(only.as_bytes()),
                        if d == Delimiter::TAB { "\\t" } else { d.name() },
                        Delimiter::COMMA,
                    );
                    return Err(s(Error::Csv { path: p, line: header_line, message }));
                }
                let available =
                    header.iter().map(|h| name_excerpt(h.as_bytes())).collect::<Vec<_>>().join(", ");
                return Err(s(Error::MissingColumn { path: p, column: column.into(), available }));
            }
            index.push(found.first().copied());
        }
        let mut time = TimeSteps::new(wanted[0].0);
        let mut values: Vec<Vec<f64>> = vec![Vec::new(); wanted.len()];
        let mut record = csv::ByteRecord::new();
        let mut row = 0usize;
        while rdr.read_byte_record(&mut record).map_err(|e| s(csv_error(path, e)))? {
            let line = record.position().map_or(0, csv::Position::line);
            if row as u64 >= limits.max_rows {
                return Err(s(Error::LimitExceeded {
                    path: p,
                    line,
                    what: format!("more than {} data rows", limits.max_rows),
                    limit: "max_rows".into(),
                    max: limits.max_rows,
                }));
            }
            for (j, (column, idx)) in values.iter_mut().zip(&index).enumerate() {
                let Some(idx) = *idx else { continue };
                let field = record.get(idx).unwrap_or_default();
                let parsed = std::str::from_utf8(field).ok().and_then(|f| f.parse::<f64>().ok());
                let Some(x) = parsed else {
                    let message = format!(
                        "column `{}` (data row {row}): cannot parse {} as a number",
                        header[idx],
                        quote(field)
                    );
                    return Err(s(Error::Csv { path: p, line, message }));
                };
                if !x.is_finite() {
                    return Err(s(Error::NonFinite { column: header[idx].clone(), row, value: x }));
                }
                if j == 0 {
                    time.push(x).map_err(s)?;
                }
                column.push(x);
            }
            row += 1;
        }
        if row == 0 {
            return Err(s(Error::TooShort { name, len: 0, min: 1 }));
        }
        let columns = values.into_iter().zip(&index).map(|(v, i)| i.map(|_| v)).collect();
        Ok(Table { name, header, columns })
    }
}

pub fn temp_path(ext: &str) -> TempFile {
    TempFile::new("csvreader", &format!("file.{ext}"))
}

pub fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    enc.write_all(bytes).unwrap();
    enc.finish().unwrap()
}

/// Both readers on `bytes` (gzip-compressed first if asked): the same table, or the same
/// error message.
fn same(bytes: &[u8], gz: bool, wanted: &[(&str, bool)], limits: &ReadLimits) -> Result<(), String> {
    let path = temp_path(if gz { "csv.gz" } else { "csv" });
    std::fs::write(&path, if gz { gzip(bytes) } else { bytes.to_vec() }).unwrap();
    let new = read_table(&path, wanted, limits, Delimiter::COMMA).map_err(|e| e.to_string());
    let old = oracle::read_table(&path, wanted, limits);
    std::fs::remove_file(&path).ok();
    match (&new, &old) {
        (Ok(a), Ok(b)) if a == b => Ok(()),
        (Err(a), Err(b)) if a == b => Ok(()),
        _ => Err(format!("new {:?}\nold {:?}", new.map(|t| t.header), old.map(|t| t.header))),
    }
}

const NAMES: [&str; 6] = ["t", "a", "b", " c ", "\"a\"", ""];

fn cell() -> impl Strategy<Value = String> {
    prop_oneof![
        6 => (-1e3..1e3f64).prop_map(|x| format!("{x}")),
        2 => (0u32..50).prop_map(|k| format!("{}", f64::from(k) * 1e-3)),
        1 => Just("nan".to_string()),
        1 => Just("-inf".to_string()),
        1 => Just(String::new()),
        1 => Just(" 1e3 ".to_string()),
        1 => "[0-9a-z\", .\r\n\t-]{0,8}",
        1 => Just("\"1,2\"".to_string()),
        1 => Just("\"3\"".to_string()),
    ]
}

/// Log-like texts: a header from `NAMES`, rows with a uniform time column (or not), cells
/// of numbers and junk, line breaks `\n`, `\r\n` or `\r`, blank lines, a byte order mark.
pub fn text() -> impl Strategy<Value = Vec<u8>> {
    let header = proptest::collection::vec(proptest::sample::select(NAMES.to_vec()), 1..6);
    (header, 0usize..40, any::<bool>(), 0usize..3, any::<bool>(), any::<bool>()).prop_flat_map(
        |(h, rows, uniform, eol, bom, blank)| {
            let width = h.len();
            proptest::collection::vec(proptest::collection::vec(cell(), width..width + 2), rows).prop_map(
                move |body| {
                    let eol = ["\n", "\r\n", "\r"][eol];
                    let mut text = if bom { "\u{feff}".to_string() } else { String::new() };
                    text += &(h.join(",") + eol);
                    for (k, row) in body.iter().enumerate() {
                        let mut row = row.clone();
                        if uniform {
                            row[0] = format!("{}", k as f64 * 1e-3);
                            row.truncate(h.len());
                        }
                        text += &(row.join(",") + eol);
                        if blank && k % 7 == 3 {
                            text += eol;
                        }
                    }
                    text.into_bytes()
                },
            )
        },
    )
}

pub fn limits() -> impl Strategy<Value = ReadLimits> {
    (
        prop_oneof![Just(1u64 << 20), 4u64..80],
        prop_oneof![Just(4096usize), 1usize..6],
        prop_oneof![Just(1u64 << 30), 0u64..30],
    )
        .prop_map(|(max_line_bytes, max_fields, max_rows)| ReadLimits {
            max_line_bytes,
            max_fields,
            max_rows,
        })
}

pub fn wanted() -> impl Strategy<Value = Vec<(&'static str, bool)>> {
    proptest::collection::vec(
        (proptest::sample::select(vec!["t", "a", "b", "c", "\"a\"", "x"]), any::<bool>()),
        1..4,
    )
    .prop_map(|mut w| {
        w[0].1 = true;
        w
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    /// Small files, in one chunk: the same result as the old reader, errors included.
    #[test]
    fn small_files_read_as_before(text in text(), gz in any::<bool>(), wanted in wanted(), limits in limits()) {
        same(&text, gz, &wanted, &limits).map_err(TestCaseError::fail)?;
    }

    /// The number parser is `str::parse::<f64>`, bit for bit, accepted texts included.
    #[test]
    fn numbers_parse_as_the_standard_library(s in "[-+]?[0-9]{0,25}[.]?[0-9]{0,25}([eE][-+]?[0-9]{0,4})?|[-+0-9.eEinfatyINFATY_x]{0,12}") {
        let std = s.parse::<f64>().ok().map(f64::to_bits);
        let field = format!(" ,{s}\n");
        let path = temp_path("csv");
        std::fs::write(&path, format!("t,x\n0,{s}\n").as_bytes()).unwrap();
        let read = read_table(&path, &[("t", true), ("x", true)], &ReadLimits::default(), Delimiter::COMMA);
        std::fs::remove_file(&path).ok();
        let ours = read.ok().and_then(|t| t.columns[1].as_ref().map(|c| c[0].to_bits()));
        // A field the reader refuses is either unparsable or not finite.
        prop_assert_eq!(ours, std.filter(|b| f64::from_bits(*b).is_finite()), "{:?}", field);
    }

    #[test]
    fn round_trip_formats_parse_exactly(bits in any::<u64>()) {
        let x = f64::from_bits(bits);
        if x.is_finite() {
            let path = temp_path("csv");
            std::fs::write(&path, format!("t,x,y\n0,{x},{x:e}\n").as_bytes()).unwrap();
            let wanted = [("t", true), ("x", true), ("y", true)];
            let t = read_table(&path, &wanted, &ReadLimits::default(), Delimiter::COMMA).unwrap();
            std::fs::remove_file(&path).ok();
            prop_assert_eq!(t.columns[1].as_ref().unwrap()[0].to_bits(), bits);
            prop_assert_eq!(t.columns[2].as_ref().unwrap()[0].to_bits(), bits);
        }
    }
}

/// The number parser on edge cases (signs, exponents, `nan`/`inf`, overflow, subnormals, a
/// 309-digit integer, junk, invalid UTF-8): `str::parse::<f64>` of the trimmed field, bit for
/// bit, and a field it refuses (or a non-finite value) is an error.
#[test]
fn numbers_parse_as_the_standard_library_on_edge_cases() {
    let cases = [
        "0",
        "-0",
        "+1",
        "1.",
        ".5",
        "-.5e-3",
        "1e",
        "1e+",
        "e5",
        ".",
        "+",
        "-",
        "",
        "1.2.3",
        "1e5",
        "1E-5",
        "nan",
        "NaN",
        "-inf",
        "+Infinity",
        "inf0",
        "0x10",
        "1_000",
        "1e999",
        "-1e-999",
        "2.2250738585072011e-308",
        "4.9e-324",
        "1.7976931348623157e308",
        "179769313486231580793728971405303415079934132710037826936173778980444968292764750946649017977587207096330286416692887910946555547851940402630657488671505820681908902000708383676273854845817711531764475730270069855571366959622842914819860834936475292719074168444365510704342711559699508093042880177904174497791.9999999",
        "0.30000000000000004",
        "123456789012345678901234567890",
        " 1",
        "1 ",
        "١",
    ];
    let cases = cases.iter().map(|c| c.as_bytes().to_vec()).chain([b"\xff1".to_vec()]);
    for c in cases {
        let std = std::str::from_utf8(&c).ok().and_then(|s| s.trim().parse::<f64>().ok());
        let path = temp_path("csv");
        std::fs::write(&path, [b"t,x\n0,".as_slice(), &c, b"\n"].concat()).unwrap();
        let read = read_table(&path, &[("t", true), ("x", true)], &ReadLimits::default(), Delimiter::COMMA);
        std::fs::remove_file(&path).ok();
        let ours = read.ok().and_then(|t| t.columns[1].as_ref().map(|c| c[0].to_bits()));
        assert_eq!(
            ours,
            std.filter(|x| x.is_finite()).map(f64::to_bits),
            "{:?}",
            String::from_utf8_lossy(&c)
        );
    }
}

/// A log of `rows` rows, 6 columns, `\n` or `\r\n`, about 60 bytes a row.
fn big(rows: usize, eol: &str) -> String {
    let mut s = format!("t,a,b,c,d,e{eol}");
    for k in 0..rows {
        let x = (k as f64 * 0.37).sin();
        s +=
            &format!("{},{x},{},{},-0.000000000000000000000031,{k}{eol}", k as f64 * 1e-4, x * 1e-7, 2.0 * x);
    }
    s
}

#[test]
fn large_files_read_as_before_with_a_fault_anywhere() {
    let wanted = [("t", true), ("a", true), ("c", true), ("e", false), ("zz", false)];
    let rows = 60_000; // about 3.5 MB: a dozen chunks
    for eol in ["\n", "\r\n"] {
        let clean = big(rows, eol);
        let lines: Vec<&str> = clean.split_inclusive(eol).collect();
        // (what, field, new text): the field of one row replaced.
        let faults = [
            ("none", 1, None),
            ("bad number", 1, Some("0.1x")),
            ("nan", 2, Some("nan")),
            ("empty", 3, Some("")),
            ("ragged", 2, Some("1,2")),
            ("quoted", 1, Some("\"0.5\"")),
            ("quoted comma", 4, Some("\"1,5\"")),
            ("line break", 2, Some("1\n\n")),
            ("time", 0, Some("1e3")),
            ("repeated time", 0, Some("0")),
        ];
        for (name, field, new) in faults {
            for at in [1, 2, 4_000, 4_001, 37_777, rows] {
                let mut text: String = lines[..at].concat();
                let mut cells: Vec<String> =
                    lines[at].trim_end_matches(['\r', '\n']).split(',').map(String::from).collect();
                if let Some(new) = new {
                    cells[field] = new.to_string();
                }
                text += &(cells.join(",") + eol);
                text += &lines[at + 1..].concat();
                let gz = at % 2 == 1;
                same(text.as_bytes(), gz, &wanted, &ReadLimits::default())
                    .unwrap_or_else(|e| panic!("{name} at line {at}, gz {gz}, eol {eol:?}: {e}"));
            }
        }
        // The row limit inside a batch, and a quoted record that switches parsers.
        for max_rows in [0, 1, 5_000, 100_000, rows as u64 - 1, rows as u64] {
            let limits = ReadLimits { max_rows, ..ReadLimits::default() };
            same(clean.as_bytes(), false, &wanted, &limits)
                .unwrap_or_else(|e| panic!("max_rows {max_rows}: {e}"));
        }
    }
}
