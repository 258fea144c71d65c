//! A report as a small document (headings, tables, lines of text) rendered as an aligned
//! plain-text table or as Markdown, so that `greybox fit --format table|markdown` print the
//! same content.
//!
//! Column widths are counted in characters (`µ`, `Ω`, `²` are one), so the columns line up
//! whatever the length of the names (long log names in per-log rows).

/// Alignment of a table column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Align {
    /// Names, units.
    Left,
    /// Numbers.
    Right,
}

/// A table: a header row and data rows of the same length (shorter rows are padded).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    /// Column titles.
    pub header: Vec<String>,
    /// Alignment per column (missing entries: right).
    pub align: Vec<Align>,
    /// Rows of cells.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with these column titles and alignments and no rows.
    pub fn new(header: &[(&str, Align)]) -> Self {
        Self {
            header: header.iter().map(|(h, _)| h.to_string()).collect(),
            align: header.iter().map(|(_, a)| *a).collect(),
            rows: Vec::new(),
        }
    }
    /// Appends a row.
    pub fn push(&mut self, row: Vec<String>) {
        self.rows.push(row);
    }
    fn cols(&self) -> usize {
        self.rows.iter().map(Vec::len).chain([self.header.len()]).max().unwrap_or(0)
    }
    fn align(&self, j: usize) -> Align {
        self.align.get(j).copied().unwrap_or(Align::Right)
    }
    fn cell(row: &[String], j: usize) -> &str {
        row.get(j).map_or("", String::as_str)
    }
    /// Column widths in characters.
    fn widths(&self) -> Vec<usize> {
        (0..self.cols())
            .map(|j| {
                std::iter::once(&self.header)
                    .chain(&self.rows)
                    .map(|r| Self::cell(r, j).chars().count())
                    .max()
                    .unwrap_or(0)
            })
            .collect()
    }
}

/// One block of a report.
#[derive(Clone, Debug, PartialEq)]
pub enum Block {
    /// A section title.
    Heading(String),
    /// A table.
    Table(Table),
    /// A line of text (a remark, a legend, a warning).
    Line(String),
}

/// A report: blocks in reading order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Document {
    /// The blocks.
    pub blocks: Vec<Block>,
}

fn pad(s: &str, width: usize, align: Align) -> String {
    let fill = " ".repeat(width.saturating_sub(s.chars().count()));
    match align {
        Align::Left => format!("{s}{fill}"),
        Align::Right => format!("{fill}{s}"),
    }
}

impl Document {
    /// Appends a heading.
    pub fn heading(&mut self, s: impl Into<String>) {
        self.blocks.push(Block::Heading(s.into()));
    }
    /// Appends a line of text.
    pub fn line(&mut self, s: impl Into<String>) {
        self.blocks.push(Block::Line(s.into()));
    }
    /// Appends a table (nothing for a table without rows).
    pub fn table(&mut self, t: Table) {
        if !t.rows.is_empty() {
            self.blocks.push(Block::Table(t));
        }
    }
    /// Appends the blocks of another document.
    pub fn extend(&mut self, other: Document) {
        self.blocks.extend(other.blocks);
    }

    /// Plain text: headings on their own line after a blank line, tables indented by two
    /// spaces with columns padded to the widest cell (two spaces between columns), lines
    /// as they are. Ends with a newline.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        for (i, b) in self.blocks.iter().enumerate() {
            match b {
                Block::Heading(h) => {
                    if i > 0 {
                        out.push('\n');
                    }
                    out.push_str(h);
                    out.push('\n');
                }
                Block::Line(l) => {
                    out.push_str(l);
                    out.push('\n');
                }
                Block::Table(t) => {
                    let w = t.widths();
                    for row in std::iter::once(&t.header).chain(&t.rows) {
                        let cells: Vec<String> =
                            (0..w.len()).map(|j| pad(Table::cell(row, j), w[j], t.align(j))).collect();
                        out.push_str("  ");
                        out.push_str(cells.join("  ").trim_end());
                        out.push('\n');
                    }
                }
            }
        }
        out
    }

    /// GitHub-flavoured Markdown: `###` headings, pipe tables with their alignment, lines
    /// as paragraphs. Pipes inside cells are escaped.
    pub fn to_markdown(&self) -> String {
        let esc = |s: &str| s.replace('|', "\\|");
        let mut out = String::new();
        for b in &self.blocks {
            match b {
                Block::Heading(h) => out.push_str(&format!("\n### {}\n\n", esc(h))),
                Block::Line(l) => out.push_str(&format!("{}\n\n", esc(l))),
                Block::Table(t) => {
                    // Trailing columns empty in the header and every row (a status column
                    // with nothing to say) are left out, not drawn empty.
                    let blank = |j: usize| {
                        std::iter::once(&t.header).chain(&t.rows).all(|r| Table::cell(r, j).trim().is_empty())
                    };
                    let n = (0..t.cols()).rev().find(|&j| !blank(j)).map_or(0, |j| j + 1);
                    let row = |r: &[String]| {
                        let cells: Vec<String> = (0..n).map(|j| esc(Table::cell(r, j))).collect();
                        format!("| {} |\n", cells.join(" | "))
                    };
                    out.push_str(&row(&t.header));
                    let rule: Vec<&str> = (0..n)
                        .map(|j| match t.align(j) {
                            Align::Left => ":---",
                            Align::Right => "---:",
                        })
                        .collect();
                    out.push_str(&format!("| {} |\n", rule.join(" | ")));
                    for r in &t.rows {
                        out.push_str(&row(r));
                    }
                    out.push('\n');
                }
            }
        }
        out.trim_start().to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Document {
        let mut d = Document::default();
        d.heading("parameters");
        let mut t = Table::new(&[("parameter", Align::Left), ("estimate", Align::Right)]);
        t.push(vec!["r_s[a-very-long-log-name]".into(), "900.00 mΩ".into()]);
        t.push(vec!["l_s".into(), "4.5000 mH".into()]);
        d.table(t);
        d.line("a|b");
        d
    }

    #[test]
    fn markdown_leaves_out_an_empty_trailing_column() {
        let mut d = Document::default();
        let mut t = Table::new(&[("parameter", Align::Left), ("estimate", Align::Right), ("", Align::Left)]);
        t.push(vec!["r_s".into(), "1".into(), String::new()]);
        d.table(t);
        let md = d.to_markdown();
        assert!(md.starts_with("| parameter | estimate |\n| :--- | ---: |\n| r_s | 1 |"), "{md}");
    }

    #[test]
    fn text_columns_align_whatever_the_name_length() {
        let text = sample().to_text();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "parameters");
        // The estimates end in the same column (right-aligned), counted in characters.
        let ends: Vec<usize> = lines[1..4].iter().map(|l| l.chars().count()).collect();
        assert_eq!(ends[0], ends[1]);
        assert_eq!(ends[1], ends[2], "{text}");
        assert!(lines[3].starts_with("  l_s "));
    }

    #[test]
    fn markdown_tables_carry_alignment_and_escape_pipes() {
        let md = sample().to_markdown();
        assert!(md.starts_with("### parameters\n\n| parameter | estimate |\n| :--- | ---: |\n"), "{md}");
        assert!(md.contains("a\\|b"));
    }
}
