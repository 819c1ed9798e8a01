//! The one Markdown table writer of the reports: a header, then rows of cells, each cell
//! kept to its column (a `|` or a line break in a cell would split the table).

use std::fmt::{self, Display};

/// A Markdown table built row by row.
///
/// ```
/// # use ricochet_lab::table::Table;
/// let mut t = Table::new(["scene", "ms/step"]);
/// t.row(["pyramid | 100", "1.5"]);
/// assert_eq!(
///     t.to_string(),
///     "| scene | ms/step |\n|---|---|\n| pyramid \\| 100 | 1.5 |\n"
/// );
/// ```
#[derive(Debug, Clone)]
pub struct Table {
    columns: usize,
    text: String,
}

impl Table {
    /// A table of these column names.
    pub fn new<I>(header: I) -> Table
    where
        I: IntoIterator,
        I::Item: Display,
    {
        let mut t = Table {
            columns: 0,
            text: String::new(),
        };
        t.columns = t.line(header);
        t.text += &"|---".repeat(t.columns);
        t.text += "|\n";
        t
    }

    /// Appends a row. Its cells fill the columns from the left; a row of more cells than
    /// columns is a bug of the report, caught in its tests.
    pub fn row<I>(&mut self, cells: I) -> &mut Table
    where
        I: IntoIterator,
        I::Item: Display,
    {
        let n = self.line(cells);
        assert!(
            n <= self.columns,
            "a row of {n} cells in a table of {} columns",
            self.columns
        );
        self
    }

    /// Whether the table has no row.
    pub fn is_empty(&self) -> bool {
        self.text.lines().count() <= 2
    }

    fn line<I>(&mut self, cells: I) -> usize
    where
        I: IntoIterator,
        I::Item: Display,
    {
        let mut n = 0;
        for cell in cells {
            self.text += "| ";
            self.text += &escape(&cell.to_string());
            self.text += " ";
            n += 1;
        }
        self.text += "|\n";
        n
    }
}

impl Display for Table {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.text)
    }
}

/// A cell's text kept to its cell: `|` escaped, line breaks as spaces.
fn escape(cell: &str) -> String {
    cell.replace('|', "\\|").replace(['\n', '\r'], " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cell_cannot_split_its_row() {
        let mut t = Table::new(["a", "b"]);
        t.row(["x|y", "two\nlines"]);
        let text = t.to_string();
        assert_eq!(text.lines().count(), 3, "{text}");
        assert_eq!(text.lines().nth(2), Some("| x\\|y | two lines |"));
        assert!(!t.is_empty());
        assert!(Table::new(["a"]).is_empty());
    }

    #[test]
    #[should_panic(expected = "a row of 3 cells in a table of 2 columns")]
    fn a_row_wider_than_the_header_is_caught() {
        Table::new(["a", "b"]).row([1, 2, 3]);
    }
}
