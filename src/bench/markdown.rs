//! Markdown for the benches' reports: tables as the CLI prints them, and the same text made
//! into a results page's body.

/// A markdown table: a header row and rows of cells (pipes in cells are not escaped: the
/// benches' cells have none).
#[derive(Clone, Debug, Default)]
pub struct Table {
    /// Column headings.
    pub head: Vec<String>,
    /// One entry per row, as many cells as headings.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with these headings and no rows.
    pub fn new<S: ToString>(head: &[S]) -> Table {
        Table {
            head: head.iter().map(ToString::to_string).collect(),
            rows: Vec::new(),
        }
    }

    /// Adds a row.
    pub fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }

    /// The table, one line a row: `| a | b |`, then `|---|---|`, then the rows.
    pub fn lines(&self) -> Vec<String> {
        let line = |cells: &[String]| format!("| {} |", cells.join(" | "));
        let mut out = vec![
            line(&self.head),
            format!("|{}", "---|".repeat(self.head.len())),
        ];
        out.extend(self.rows.iter().map(|r| line(r)));
        out
    }

    /// The table as text, a newline after each line.
    pub fn text(&self) -> String {
        self.lines().iter().map(|l| format!("{l}\n")).collect()
    }
}

/// A value with `digits` decimals, or "–" where there is none.
pub fn dash(x: Option<f64>, digits: usize) -> String {
    x.map_or("–".to_string(), |g| format!("{g:.digits$}"))
}

/// Whether a line is a row of a markdown table.
fn is_table_line(line: &str) -> bool {
    line.starts_with('|')
}

/// A report's text made into markdown a book renders as printed: each line outside a table
/// its own paragraph, each table with a blank line before and after.
pub fn page_body(text: &str) -> String {
    let mut out = String::new();
    let mut last: Option<bool> = None; // whether the previous line was a table row
    let mut gap = false; // a blank line since the previous line
    for line in text.lines() {
        if line.trim().is_empty() {
            gap = true;
            continue;
        }
        let table = is_table_line(line);
        if last.is_some() && (gap || !(table && last == Some(true))) {
            out.push('\n');
        }
        gap = false;
        out.push_str(line.trim_end());
        out.push('\n');
        last = Some(table);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_prints_head_rule_and_rows() {
        let mut t = Table::new(&["a", "b"]);
        t.row(vec!["1".into(), dash(None, 2)]);
        assert_eq!(t.text(), "| a | b |\n|---|---|\n| 1 | – |\n");
    }

    #[test]
    fn a_page_body_separates_paragraphs_and_tables() {
        let text = "mesh x\nadapter y\n| a |\n|---|\n| 1 |\n\n| b |\n|---|\nnote\n\nmore";
        assert_eq!(
            page_body(text),
            "mesh x\n\nadapter y\n\n| a |\n|---|\n| 1 |\n\n| b |\n|---|\n\nnote\n\nmore\n"
        );
    }
}
