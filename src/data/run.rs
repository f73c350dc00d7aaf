//! Measured runs: repetitions of the same experiment, one CSV file each.
//!
//! Columns (header names, any order): `t` (s, uniform steps), `q1..qn` (rad
//! or m), `tau1..taun` (measured or commanded motor torque, N·m or N),
//! optionally `r1..rn` (the reference), `qd1..qdn` and `qdd1..qddn`
//! (measured velocities/accelerations; used instead of differentiation when
//! present in every file). Any other column is an error, as are NaN/Inf,
//! non-numbers, non-uniform time, and repetitions of different lengths or
//! time grids. A run is a folder (every `*.csv` in it except `reference.csv`,
//! in name order) or an explicit list of files.

use crate::error::{Error, Result};
use crate::io::Table;
use std::path::{Path, PathBuf};

/// One repetition: samples k = 0..N at times t_k (rows: per sample, n values).
#[derive(Debug, Clone, PartialEq)]
pub struct Repetition {
    /// Times (s).
    pub t: Vec<f64>,
    /// Measured positions.
    pub q: Vec<Vec<f64>>,
    /// Measured torques.
    pub tau: Vec<Vec<f64>>,
    /// Reference positions, if recorded.
    pub r: Option<Vec<Vec<f64>>>,
    /// Measured velocities, if recorded.
    pub qd: Option<Vec<Vec<f64>>>,
    /// Measured accelerations, if recorded.
    pub qdd: Option<Vec<Vec<f64>>>,
}

impl Repetition {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Number of joints.
    pub fn n_joints(&self) -> usize {
        self.q.first().map_or(0, |v| v.len())
    }

    /// Writes the repetition in the run format (atomically).
    pub fn write(&self, path: &Path) -> Result<()> {
        let n = self.n_joints();
        let mut header = vec!["t".to_string()];
        header.extend((1..=n).map(|i| format!("q{i}")));
        header.extend((1..=n).map(|i| format!("tau{i}")));
        let opt = [("r", &self.r), ("qd", &self.qd), ("qdd", &self.qdd)];
        for (p, v) in &opt {
            if v.is_some() {
                header.extend((1..=n).map(|i| format!("{p}{i}")));
            }
        }
        let rows = (0..self.len()).map(|k| {
            let mut row = Vec::with_capacity(header.len());
            row.push(self.t[k]);
            row.extend_from_slice(&self.q[k]);
            row.extend_from_slice(&self.tau[k]);
            for (_, v) in &opt {
                if let Some(v) = v {
                    row.extend_from_slice(&v[k]);
                }
            }
            row
        });
        crate::io::write_csv(path, &header, rows)
    }

    /// Reads one repetition for a robot with `n` joints, with the strict checks
    /// described in the module documentation.
    pub fn read(path: &Path, n: usize) -> Result<Repetition> {
        let t = Table::read(path)?;
        Self::from_table(&t, n)
    }

    /// Extracts a repetition from a parsed table.
    pub fn from_table(t: &Table, n: usize) -> Result<Repetition> {
        let path = &t.path;
        for c in &t.columns {
            if !known_column(c, n) {
                return Err(Error::Data {
                    path: path.clone(),
                    row: 0,
                    column: c.clone(),
                    msg: format!("unknown column; expected t, q1..q{n}, tau1..tau{n} and optionally r*, qd*, qdd* (for {n} joints)"),
                });
            }
        }
        let it = t.require("t")?;
        let iq = t.numbered("q", n)?;
        let itau = t.numbered("tau", n)?;
        let opt = |p: &str| -> Result<Option<Vec<usize>>> {
            if (1..=n).any(|i| t.index(&format!("{p}{i}")).is_some()) {
                Ok(Some(t.numbered(p, n)?))
            } else {
                Ok(None)
            }
        };
        let (ir, iqd, iqdd) = (opt("r")?, opt("qd")?, opt("qdd")?);
        let times = t.column(it);
        if times.len() < 3 {
            return Err(Error::Data {
                path: path.clone(),
                row: times.len(),
                column: "t".into(),
                msg: "expected at least 3 samples".into(),
            });
        }
        let dt = (times[times.len() - 1] - times[0]) / (times.len() - 1) as f64;
        if dt.is_nan() || dt <= 0.0 {
            return Err(Error::Data {
                path: path.clone(),
                row: 2,
                column: "t".into(),
                msg: "time must increase".into(),
            });
        }
        for (k, w) in times.windows(2).enumerate() {
            let d = w[1] - w[0];
            if (d - dt).abs() > 1e-3 * dt {
                return Err(Error::Data {
                    path: path.clone(),
                    row: k + 2,
                    column: "t".into(),
                    msg: format!("non-uniform time: step {d} s, expected {dt} s (the mean step)"),
                });
            }
        }
        let pick = |idx: &[usize]| -> Vec<Vec<f64>> { t.rows.iter().map(|r| idx.iter().map(|&i| r[i]).collect()).collect() };
        Ok(Repetition {
            t: times,
            q: pick(&iq),
            tau: pick(&itau),
            r: ir.as_deref().map(pick),
            qd: iqd.as_deref().map(pick),
            qdd: iqdd.as_deref().map(pick),
        })
    }
}

fn known_column(c: &str, n: usize) -> bool {
    if c == "t" {
        return true;
    }
    for p in ["qdd", "qd", "q", "tau", "r"] {
        if let Some(rest) = c.strip_prefix(p) {
            if let Ok(i) = rest.parse::<usize>() {
                // a number beyond n is reported by `numbered` with a clearer message
                return i >= 1 && (i <= n + 1) && !rest.starts_with('0');
            }
        }
    }
    false
}

/// A run: N_r repetitions on a common time grid.
#[derive(Debug, Clone)]
pub struct Run {
    /// Where each repetition came from (for messages; empty paths for in-memory runs).
    pub files: Vec<PathBuf>,
    /// The repetitions.
    pub reps: Vec<Repetition>,
}

impl Run {
    /// Builds a run from repetitions, checking that they agree (length, time
    /// grid within 1e-6 of a step, optional columns present in all or none).
    pub fn new(files: Vec<PathBuf>, reps: Vec<Repetition>) -> Result<Run> {
        if reps.is_empty() {
            return Err(Error::invalid("run", "files", "expected at least one repetition"));
        }
        let name = |i: usize| files.get(i).cloned().unwrap_or_else(|| PathBuf::from(format!("repetition {}", i + 1)));
        let r0 = &reps[0];
        let dt = (r0.t[r0.len() - 1] - r0.t[0]) / (r0.len() - 1) as f64;
        for (i, r) in reps.iter().enumerate().skip(1) {
            if r.len() != r0.len() {
                return Err(Error::Data {
                    path: name(i),
                    row: r.len().min(r0.len()) + 1,
                    column: "t".into(),
                    msg: format!(
                        "{} samples, but {} has {}: repetitions must have the same length",
                        r.len(),
                        name(0).display(),
                        r0.len()
                    ),
                });
            }
            if r.n_joints() != r0.n_joints() {
                return Err(Error::dim(format!("joints in {}", name(i).display()), r0.n_joints(), r.n_joints()));
            }
            // the time grid may be offset (continuous recording cut into periods) but must have the same step
            let off = r.t[0] - r0.t[0];
            for k in 0..r.len() {
                if (r.t[k] - off - r0.t[k]).abs() > 1e-3 * dt {
                    return Err(Error::Data {
                        path: name(i),
                        row: k + 1,
                        column: "t".into(),
                        msg: format!("time grid differs from {} (t = {} vs {})", name(0).display(), r.t[k] - off, r0.t[k]),
                    });
                }
            }
            for (col, a, b) in [
                ("r1", r.r.is_some(), r0.r.is_some()),
                ("qd1", r.qd.is_some(), r0.qd.is_some()),
                ("qdd1", r.qdd.is_some(), r0.qdd.is_some()),
            ] {
                if a != b {
                    return Err(Error::Data {
                        path: name(i),
                        row: 0,
                        column: col.into(),
                        msg: format!(
                            "column present in one repetition but not in {}: use the same columns in all files",
                            name(0).display()
                        ),
                    });
                }
            }
        }
        Ok(Run { files, reps })
    }

    /// Reads a run: each path is a CSV file or a folder (all `*.csv` except
    /// `reference.csv`, sorted by name), for a robot with `n` joints.
    pub fn read(paths: &[PathBuf], n: usize) -> Result<Run> {
        let files = expand(paths)?;
        let reps = files.iter().map(|f| Repetition::read(f, n)).collect::<Result<Vec<_>>>()?;
        Run::new(files, reps)
    }

    /// Number of repetitions N_r.
    pub fn n_reps(&self) -> usize {
        self.reps.len()
    }

    /// Number of joints.
    pub fn n_joints(&self) -> usize {
        self.reps[0].n_joints()
    }

    /// Sample step (s).
    pub fn dt(&self) -> f64 {
        let t = &self.reps[0].t;
        (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64
    }

    /// The folder of the run, if it was read from one.
    pub fn folder(&self) -> Option<PathBuf> {
        self.files.first().and_then(|f| f.parent().map(|p| p.to_path_buf()))
    }
}

/// Expands folders into their CSV files (sorted; `reference.csv` skipped).
pub fn expand(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let rd = std::fs::read_dir(p).map_err(|e| Error::io(p, e))?;
            let mut v: Vec<PathBuf> = rd
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| f.extension().is_some_and(|e| e == "csv") && f.file_name().is_some_and(|n| n != "reference.csv"))
                .collect();
            v.sort();
            if v.is_empty() {
                return Err(Error::invalid(p.display().to_string(), "run", "the folder holds no CSV repetition files"));
            }
            out.extend(v);
        } else if p.exists() {
            out.push(p.clone());
        } else {
            return Err(Error::io(p, std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or folder")));
        }
    }
    if out.is_empty() {
        return Err(Error::invalid("run", "files", "expected at least one CSV file or folder"));
    }
    Ok(out)
}
