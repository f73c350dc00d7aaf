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

/// A streaming reader of a states CSV (same format and checks as
/// [`States::read`]): rows are parsed block by block, so memory does not grow
/// with the file length.
pub struct StatesReader {
    path: std::path::PathBuf,
    rdr: csv::Reader<std::io::BufReader<std::fs::File>>,
    columns: Vec<String>,
    idx: [Vec<usize>; 3],
    it: Option<usize>,
    row: usize,
    /// Only the rows whose `segment` column (index) holds this value.
    segment: Option<(usize, i64)>,
    /// Rows that passed the segment filter so far.
    selected: usize,
    rec: csv::StringRecord,
}

/// A block of consecutive rows from a [`StatesReader`].
#[derive(Debug, Clone, Default)]
pub struct StateBlock {
    /// `t` per row (if the file has a `t` column).
    pub t: Vec<f64>,
    /// q, q̇, q̈ of every row, each n values, row after row.
    pub q: Vec<f64>,
    /// Velocities.
    pub qd: Vec<f64>,
    /// Accelerations.
    pub qdd: Vec<f64>,
    /// 1-based data row (in the file) of the first row of the block.
    pub first_row: usize,
}

impl StateBlock {
    /// Number of rows in the block.
    pub fn len(&self, n: usize) -> usize {
        self.q.len().checked_div(n).unwrap_or(0)
    }
}

impl StatesReader {
    /// Opens `path` and checks its header for a robot with `n` joints.
    pub fn open(path: &Path, n: usize) -> Result<StatesReader> {
        use crate::error::Error;
        let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::All)
            .flexible(true)
            .comment(Some(b'#'))
            .from_reader(std::io::BufReader::with_capacity(1 << 16, f));
        let headers = rdr.headers().map_err(|e| Error::parse(path, format!("header: {e}")))?.clone();
        let columns: Vec<String> = headers.iter().map(|s| s.to_string()).collect();
        if columns.is_empty() || columns.iter().all(|c| c.is_empty()) {
            return Err(Error::parse(path, "empty file: expected a header row of column names"));
        }
        for (i, c) in columns.iter().enumerate() {
            let msg = if c.is_empty() {
                "empty column name in header"
            } else if columns[..i].contains(c) {
                "duplicate column name"
            } else {
                continue;
            };
            return Err(Error::Data {
                path: path.into(),
                row: 0,
                column: if c.is_empty() { format!("#{}", i + 1) } else { c.clone() },
                msg: msg.into(),
            });
        }
        let header = Table {
            path: path.into(),
            columns: columns.clone(),
            rows: Vec::new(),
        };
        let idx = [header.numbered("q", n)?, header.numbered("qd", n)?, header.numbered("qdd", n)?];
        Ok(StatesReader {
            path: path.into(),
            rdr,
            it: header.index("t"),
            columns,
            idx,
            row: 0,
            segment: None,
            selected: 0,
            rec: csv::StringRecord::new(),
        })
    }

    /// Keeps only the rows whose `segment` column equals `k` (`every` then
    /// counts those rows): in `idexp excite`'s trajectory.csv, 0 is the
    /// lead-in, k ≥ 1 period k, −1 the lead-out. Errors when the file has no
    /// `segment` column.
    pub fn only_segment(&mut self, k: i64) -> Result<()> {
        let Some(i) = self.columns.iter().position(|c| c == "segment") else {
            return Err(crate::error::Error::Data {
                path: self.path.clone(),
                row: 0,
                column: "segment".into(),
                msg: format!(
                    "segment {k} asked for, but the file has no `segment` column (idexp excite's trajectory.csv has one: \
                     0 lead-in, k period k, -1 lead-out)"
                ),
            });
        };
        self.segment = Some((i, k));
        Ok(())
    }

    /// True if the file has a `t` column.
    pub fn has_t(&self) -> bool {
        self.it.is_some()
    }

    /// Reads up to `max_rows` rows into `block` (cleared first), keeping every
    /// `every`-th data row (rows 1, 1 + every, …; of the segment's rows only,
    /// after [`StatesReader::only_segment`]). Returns the number of rows
    /// read into the block (0 at the end of the file). Errors name the file,
    /// the 1-based data row and the column.
    pub fn next_block(&mut self, max_rows: usize, every: usize, block: &mut StateBlock) -> Result<usize> {
        use crate::error::Error;
        block.t.clear();
        block.q.clear();
        block.qd.clear();
        block.qdd.clear();
        let every = every.max(1);
        let mut got = 0;
        let mut vals = vec![0.0; self.columns.len()];
        while got < max_rows {
            let more = self.rdr.read_record(&mut self.rec).map_err(|e| {
                let line = e.position().map(|p| format!(" (line {})", p.line())).unwrap_or_default();
                Error::parse(&self.path, format!("data row {}{line}: {e}", self.row + 1))
            })?;
            if !more {
                break;
            }
            self.row += 1;
            let r = self.row;
            let rec = &self.rec;
            if rec.len() != self.columns.len() {
                return Err(Error::Data {
                    path: self.path.clone(),
                    row: r,
                    column: self
                        .columns
                        .get(rec.len().min(self.columns.len().saturating_sub(1)))
                        .cloned()
                        .unwrap_or_default(),
                    msg: format!("expected {} values as in the header, found {}", self.columns.len(), rec.len()),
                });
            }
            for (c, cell) in rec.iter().enumerate() {
                let v: f64 = cell.parse().map_err(|_| Error::Data {
                    path: self.path.clone(),
                    row: r,
                    column: self.columns[c].clone(),
                    msg: format!("expected a number, found {cell:?}"),
                })?;
                if !v.is_finite() {
                    return Err(Error::Data {
                        path: self.path.clone(),
                        row: r,
                        column: self.columns[c].clone(),
                        msg: format!("expected a finite number, found {cell}"),
                    });
                }
                vals[c] = v;
            }
            if let Some((i, k)) = self.segment {
                if vals[i] != k as f64 {
                    continue;
                }
            }
            self.selected += 1;
            if (self.selected - 1) % every != 0 {
                continue;
            }
            if got == 0 {
                block.first_row = r;
            }
            if let Some(i) = self.it {
                block.t.push(vals[i]);
            }
            block.q.extend(self.idx[0].iter().map(|&i| vals[i]));
            block.qd.extend(self.idx[1].iter().map(|&i| vals[i]));
            block.qdd.extend(self.idx[2].iter().map(|&i| vals[i]));
            got += 1;
        }
        Ok(got)
    }

    /// Data rows read so far (all rows, before `every`).
    pub fn rows_read(&self) -> usize {
        self.row
    }
}
