//! One repetition of a run: one CSV file of `t`, `q*`, `tau*` and the optional
//! columns (see the module documentation of [`super`]).

use crate::error::{Error, Result};
use crate::io::Table;
use std::path::Path;

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
        self.write_drive(path, None, true)
    }

    /// Writes the repetition with motor currents `cur1..curn` = τ_j / `scale_j`
    /// (scale = s·k_t·N per joint, [`crate::robot::Drive::torque_per_ampere`])
    /// when `scale` is given, and the torques `tau1..taun` when `torques`.
    pub fn write_drive(&self, path: &Path, scale: Option<&[f64]>, torques: bool) -> Result<()> {
        let n = self.n_joints();
        let mut header = vec!["t".to_string()];
        header.extend((1..=n).map(|i| format!("q{i}")));
        if torques || scale.is_none() {
            header.extend((1..=n).map(|i| format!("tau{i}")));
        }
        if scale.is_some() {
            header.extend((1..=n).map(|i| format!("cur{i}")));
        }
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
            if torques || scale.is_none() {
                row.extend_from_slice(&self.tau[k]);
            }
            if let Some(sc) = scale {
                row.extend(self.tau[k].iter().zip(sc).map(|(t, s)| t / s));
            }
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

    /// Extracts a repetition from a parsed table (uniform time steps required).
    pub fn from_table(t: &Table, n: usize) -> Result<Repetition> {
        Self::from_table_timed(t, n, false)
    }

    /// [`Repetition::from_table`]; with `irregular`, time stamps need only
    /// increase strictly (the caller resamples them, [`crate::data::resample`]).
    pub fn from_table_timed(t: &Table, n: usize, irregular: bool) -> Result<Repetition> {
        let path = &t.path;
        for c in &t.columns {
            if !known_column(c, n) {
                return Err(Error::Data {
                    path: path.clone(),
                    row: 0,
                    column: c.clone(),
                    msg: format!("unknown column; expected t, q1..q{n}, tau1..tau{n} (or cur1..cur{n}) and optionally r*, qd*, qdd*, var_tau*, var_cur*, var_q* (for {n} joints)"),
                });
            }
        }
        let it = t.require("t")?;
        let iq = t.numbered("q", n)?;
        if t.index("tau1").is_none() && t.columns.iter().any(|c| c.starts_with("cur")) {
            return Err(Error::Data {
                path: path.clone(),
                row: 0,
                column: "tau1".into(),
                msg: format!(
                    "the run logs motor currents cur1..cur{n} but no torques tau1..tau{n}: currents need the robot's torque constants (torque_from = \"current\" or \"auto\", with torque_constant and gear_ratio in the robot file's [[drive]] entries; library: Run::read_drives)"
                ),
            });
        }
        let itau = t.numbered("tau", n)?;
        let opt = |p: &str| -> Result<Option<Vec<usize>>> {
            let present: Vec<bool> = (1..=n).map(|i| t.index(&format!("{p}{i}")).is_some()).collect();
            if let (Some(a), Some(b)) = (present.iter().position(|&x| x), present.iter().position(|&x| !x)) {
                return Err(Error::Data {
                    path: path.clone(),
                    row: 0,
                    column: format!("{p}{}", b + 1),
                    msg: format!(
                        "missing column: the file has {p}{} but not {p}{}; {p}* columns are logged for every joint ({p}1..{p}{n}) or for none",
                        a + 1,
                        b + 1
                    ),
                });
            }
            if present.iter().any(|&x| x) {
                Ok(Some(t.numbered(p, n)?))
            } else {
                Ok(None)
            }
        };
        let (ir, iqd, iqdd) = (opt("r")?, opt("qd")?, opt("qdd")?);
        if iqdd.is_some() && iqd.is_none() {
            return Err(Error::Data {
                path: path.clone(),
                row: 0,
                column: "qd1".into(),
                msg: format!(
                    "logged accelerations qdd1..qdd{n} without logged velocities qd1..qd{n}: give the drive's velocities too (or drop the qdd* columns and let idexp differentiate)"
                ),
            });
        }
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
        if irregular {
            crate::data::resample::check_increasing(path, &times)?;
        }
        for (k, w) in times.windows(2).enumerate().filter(|_| !irregular) {
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
    for p in ["var_tau", "var_cur", "var_q", "qdd", "qd", "q", "tau", "cur", "r"] {
        if let Some(rest) = c.strip_prefix(p) {
            if let Ok(i) = rest.parse::<usize>() {
                // a number beyond n is reported by `numbered` with a clearer message
                return i >= 1 && (i <= n + 1) && !rest.starts_with('0');
            }
        }
    }
    false
}
