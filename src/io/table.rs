//! Numeric CSV tables with a header row: every cell is parsed as f64 and must
//! be finite; errors name the file, the 1-based data row and the column.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// A numeric table read from a CSV file (row-major storage).
#[derive(Debug, Clone)]
pub struct Table {
    /// The file the table came from (for messages).
    pub path: PathBuf,
    /// Column names, trimmed.
    pub columns: Vec<String>,
    /// Rows of values, each of `columns.len()` finite numbers.
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// Reads and validates a CSV file: a header, then rows of finite numbers,
    /// each row as long as the header. Empty files and duplicate columns are errors.
    pub fn read(path: &Path) -> Result<Table> {
        let text = super::read_to_string(path)?;
        Table::parse(path, &text)
    }

    /// Parses CSV text (from `path`, for messages).
    pub fn parse(path: &Path, text: &str) -> Result<Table> {
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::All)
            .flexible(true)
            .comment(Some(b'#'))
            .from_reader(text.as_bytes());
        let headers = rdr.headers().map_err(|e| Error::parse(path, format!("header: {e}")))?.clone();
        let columns: Vec<String> = headers.iter().map(|s| s.to_string()).collect();
        if columns.is_empty() || columns.iter().all(|c| c.is_empty()) {
            return Err(Error::parse(path, "empty file: expected a header row of column names"));
        }
        for (i, c) in columns.iter().enumerate() {
            if c.is_empty() {
                return Err(Error::Data {
                    path: path.into(),
                    row: 0,
                    column: format!("#{}", i + 1),
                    msg: "empty column name in header".into(),
                });
            }
            if columns[..i].contains(c) {
                return Err(Error::Data {
                    path: path.into(),
                    row: 0,
                    column: c.clone(),
                    msg: "duplicate column name".into(),
                });
            }
        }
        let mut rows = Vec::new();
        for (r, rec) in rdr.records().enumerate() {
            let rec = rec.map_err(|e| {
                let line = e.position().map(|p| format!(" (line {})", p.line())).unwrap_or_default();
                Error::parse(path, format!("data row {}{line}: {e}", r + 1))
            })?;
            if rec.len() != columns.len() {
                return Err(Error::Data {
                    path: path.into(),
                    row: r + 1,
                    column: columns.get(rec.len().min(columns.len().saturating_sub(1))).cloned().unwrap_or_default(),
                    msg: format!("expected {} values as in the header, found {}", columns.len(), rec.len()),
                });
            }
            let mut row = Vec::with_capacity(columns.len());
            for (c, cell) in rec.iter().enumerate() {
                let v: f64 = cell.parse().map_err(|_| Error::Data {
                    path: path.into(),
                    row: r + 1,
                    column: columns[c].clone(),
                    msg: format!("expected a number, found {cell:?}"),
                })?;
                if !v.is_finite() {
                    return Err(Error::Data {
                        path: path.into(),
                        row: r + 1,
                        column: columns[c].clone(),
                        msg: format!("expected a finite number, found {cell}"),
                    });
                }
                row.push(v);
            }
            rows.push(row);
        }
        if rows.is_empty() {
            return Err(Error::parse(path, "no data rows after the header"));
        }
        Ok(Table {
            path: path.into(),
            columns,
            rows,
        })
    }

    /// Number of data rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when there are no rows (never for a table returned by [`Table::read`]).
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Index of a column, if present.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c == name)
    }

    /// Index of a required column, or an error naming the file and the column.
    pub fn require(&self, name: &str) -> Result<usize> {
        self.index(name).ok_or_else(|| Error::Data {
            path: self.path.clone(),
            row: 0,
            column: name.to_string(),
            msg: format!("missing column; the header has: {}", self.columns.join(", ")),
        })
    }

    /// Copy of one column's values.
    pub fn column(&self, idx: usize) -> Vec<f64> {
        self.rows.iter().map(|r| r[idx]).collect()
    }

    /// Indices of columns `prefix1..prefixN`; errors if any is missing.
    /// Also errors if a column `prefix{N+1}` exists (wrong joint count).
    pub fn numbered(&self, prefix: &str, n: usize) -> Result<Vec<usize>> {
        let idx = (1..=n).map(|i| self.require(&format!("{prefix}{i}"))).collect::<Result<Vec<_>>>()?;
        let extra = format!("{prefix}{}", n + 1);
        if self.index(&extra).is_some() {
            return Err(Error::Data {
                path: self.path.clone(),
                row: 0,
                column: extra,
                msg: format!("the robot has {n} joints but the file has more `{prefix}` columns"),
            });
        }
        Ok(idx)
    }
}
