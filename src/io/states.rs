//! Joint-state CSV files: header `q1..qn, qd1..qdn, qdd1..qddn` (extra
//! columns such as `t` are allowed and ignored; a `t` column is kept for output).

use super::Table;
use crate::error::Result;
use std::path::Path;

/// Joint states read from a CSV file.
#[derive(Debug, Clone)]
pub struct States {
    /// The `t` column, if present.
    pub t: Option<Vec<f64>>,
    /// Positions, one vector of length n per row.
    pub q: Vec<Vec<f64>>,
    /// Velocities.
    pub qd: Vec<Vec<f64>>,
    /// Accelerations.
    pub qdd: Vec<Vec<f64>>,
}

impl States {
    /// Reads a states CSV for a robot with `n` joints. Missing columns, a
    /// wrong joint count, non-numbers and NaN/Inf are errors naming the file,
    /// the row and the column.
    pub fn read(path: &Path, n: usize) -> Result<States> {
        let t = Table::read(path)?;
        Self::from_table(&t, n)
    }

    /// Extracts states from a parsed table.
    pub fn from_table(t: &Table, n: usize) -> Result<States> {
        let iq = t.numbered("q", n)?;
        let iqd = t.numbered("qd", n)?;
        let iqdd = t.numbered("qdd", n)?;
        let pick = |idx: &[usize]| t.rows.iter().map(|r| idx.iter().map(|&i| r[i]).collect()).collect::<Vec<Vec<f64>>>();
        Ok(States {
            t: t.index("t").map(|i| t.column(i)),
            q: pick(&iq),
            qd: pick(&iqd),
            qdd: pick(&iqdd),
        })
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.q.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }

    /// Header `t?, q1..qn, qd1..qdn, qdd1..qddn`.
    pub fn header(n: usize, with_t: bool) -> Vec<String> {
        let mut h = Vec::with_capacity(3 * n + 1);
        if with_t {
            h.push("t".to_string());
        }
        for p in ["q", "qd", "qdd"] {
            h.extend((1..=n).map(|i| format!("{p}{i}")));
        }
        h
    }

    /// Writes the states atomically in the same format.
    pub fn write(&self, path: &Path) -> Result<()> {
        let n = self.q.first().map(|v| v.len()).unwrap_or(0);
        let header = Self::header(n, self.t.is_some());
        let rows = (0..self.len()).map(|k| {
            let mut r = Vec::with_capacity(header.len());
            if let Some(t) = &self.t {
                r.push(t[k]);
            }
            r.extend_from_slice(&self.q[k]);
            r.extend_from_slice(&self.qd[k]);
            r.extend_from_slice(&self.qdd[k]);
            r
        });
        super::write_csv(path, &header, rows)
    }
}
