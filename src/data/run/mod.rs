//! Measured runs: repetitions of the same experiment, one CSV file each.
//!
//! Columns (header names, any order): `t` (s, uniform steps), `q1..qn` (rad
//! or m), `tau1..taun` (measured or commanded motor torque, N·m or N),
//! optionally `r1..rn` (the reference), `qd1..qdn` (the drive's logged joint
//! velocities, rad/s or m/s) and `qdd1..qddn` (logged accelerations, only
//! beside `qd*`); each of these for every joint or for none, in every file or
//! in none (how identification uses them: [`crate::ident::VelocityFrom`]).
//! Any other column is an error, as are NaN/Inf,
//! non-numbers, non-uniform time, and repetitions of different lengths or
//! time grids. A run is a folder (every `*.csv` in it except `reference.csv`,
//! in name order) or an explicit list of files.
//!
//! An **averaged run** is one CSV of the means over N_r repetitions with the
//! per-sample variances of the individual measurements (paper 000 eq. 7,
//! computed upstream): columns `var_tau1..var_taun` (required) and
//! `var_q1..var_qn` (optional) next to the usual ones. N_r comes from the
//! caller (`--repetitions`) or from `run.json` in the file's folder
//! (`{"repetitions": 50}`). Variances must be finite and positive.
//!
//! **Motor currents** ([`Run::read_drives`]): columns `cur1..curn` (A) instead
//! of, or beside, `tau1..taun`, converted with each drive's torque constant
//! k_t (N·m/A, motor side), gear ratio N and current sign s of the robot
//! file: τ_j = s_j k_t,j N_j i_j (joint side). An averaged run of currents
//! gives `var_cur*` (A²), scaled by (s k_t N)². When both torques and
//! currents are logged they must agree: per file and joint, the RMS of
//! s k_t N i − τ at most `tolerance` (default [`CURRENT_TOLERANCE`] = 5 %)
//! of the RMS of τ. The torque constants are taken as known: a scale of
//! k_t is not identified, because one common factor on every torque trades
//! off exactly against the inertial and friction parameters (θ and the
//! scale appear only as a product) unless a known payload fixes it.
//!
//! Coordinates ([`Coordinates`]): runs logged on the motor side of a coupled
//! wrist (θ = C q) are mapped to joint coordinates by [`Run::to_joint_coordinates`].

mod drives;
mod repetition;

pub use drives::{TorqueColumns, TorqueFrom, TorqueSource, CURRENT_TOLERANCE};
pub use repetition::Repetition;

use crate::error::{Error, Result};
use crate::io::Table;
use std::path::{Path, PathBuf};

/// The per-sample variances of an averaged run (one CSV of means).
#[derive(Debug, Clone, PartialEq)]
pub struct Averaged {
    /// Number of repetitions N_r the means were taken over (≥ 2).
    pub repetitions: usize,
    /// Sample variance σ²_{j,p} of the individual torque measurements (eq. 7), per sample.
    pub var_tau: Vec<Vec<f64>>,
    /// Sample variance of the individual position measurements, if given.
    pub var_q: Option<Vec<Vec<f64>>>,
}

/// Coordinates of the logged positions (`--coordinates`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Coordinates {
    /// Joint coordinates q (idexp's own).
    #[default]
    Joint,
    /// Motor-side coordinates θ = C q (C the robot's coupling matrix); torques already motor-side.
    Motor,
}

impl Coordinates {
    /// The name on the command line (`joint`, `motor`).
    pub fn name(self) -> &'static str {
        match self {
            Coordinates::Joint => "joint",
            Coordinates::Motor => "motor",
        }
    }
}

impl std::fmt::Display for Coordinates {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Coordinates {
    type Err = Error;
    fn from_str(s: &str) -> Result<Coordinates> {
        match s {
            "joint" => Ok(Coordinates::Joint),
            "motor" => Ok(Coordinates::Motor),
            _ => Err(Error::invalid("identify", "coordinates", format!("expected joint or motor, found `{s}`"))),
        }
    }
}

/// Irregular time stamps accepted and resampled ([`Run::read_drives_sampled`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplingOptions {
    /// Uniform rate (Hz) to resample to; None: the inverse median logged step.
    pub rate: Option<f64>,
    /// Largest number of samples per repetition after resampling.
    pub limit: usize,
}

impl Default for SamplingOptions {
    fn default() -> Self {
        SamplingOptions { rate: None, limit: 50_000_000 }
    }
}

/// `run.json` next to an averaged run.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RunMeta {
    repetitions: Option<usize>,
    #[serde(default)]
    source: Option<String>,
}

/// A run: N_r repetitions on a common time grid, or one averaged repetition
/// with its per-sample variances ([`Averaged`]).
#[derive(Debug, Clone)]
pub struct Run {
    /// Where each repetition came from (for messages; empty paths for in-memory runs).
    pub files: Vec<PathBuf>,
    /// The repetitions (one for an averaged run: the means).
    pub reps: Vec<Repetition>,
    /// Variances and N_r of an averaged run.
    pub averaged: Option<Averaged>,
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
        Ok(Run { files, reps, averaged: None })
    }

    /// An averaged run: the means `mean` over `repetitions` repetitions with
    /// the per-sample variances of the individual torque (and optionally
    /// position) measurements. Variances must be finite and positive and
    /// `repetitions` ≥ 2; errors name `file`, the row and the column.
    pub fn averaged(file: PathBuf, mean: Repetition, var_tau: Vec<Vec<f64>>, var_q: Option<Vec<Vec<f64>>>, repetitions: usize) -> Result<Run> {
        let n = mean.n_joints();
        if repetitions < 2 {
            return Err(Error::Data {
                path: file,
                row: 0,
                column: "var_tau1".into(),
                msg: format!(
                    "variance columns with {repetitions} repetition(s): the sample variance (eq. 7) needs N_r ≥ 2; give the number the means were taken over (`repetitions = N`, or \"repetitions\" in run.json)"
                ),
            });
        }
        for (prefix, v) in [("var_tau", Some(&var_tau)), ("var_q", var_q.as_ref())] {
            let Some(v) = v else { continue };
            if v.len() != mean.len() {
                return Err(Error::dim(format!("rows of {prefix}* in {}", file.display()), mean.len(), v.len()));
            }
            for (k, row) in v.iter().enumerate() {
                for j in 0..n {
                    let x = row[j];
                    if !(x.is_finite() && x > 0.0) {
                        return Err(Error::Data {
                            path: file,
                            row: k + 1,
                            column: format!("{prefix}{}", j + 1),
                            msg: format!(
                                "expected a positive finite variance, found {x} (a zero variance would give an infinite weight; use repetition_weights = \"joint\" if some are unknown)"
                            ),
                        });
                    }
                }
            }
        }
        Ok(Run {
            files: vec![file],
            reps: vec![mean],
            averaged: Some(Averaged { repetitions, var_tau, var_q }),
        })
    }

    /// Maps motor-side positions, velocities, accelerations and references
    /// θ = C q to joint coordinates q = C⁻¹ θ (torques are left as they are:
    /// they are motor-side in both cases); position variances map as
    /// var(q_j) = Σ_k (C⁻¹)²_{jk} var(θ_k) (independent motors).
    pub fn to_joint_coordinates(&mut self, c: &nalgebra::DMatrix<f64>) -> Result<()> {
        let n = self.n_joints();
        if c.nrows() != n || c.ncols() != n {
            return Err(Error::dim("coupling matrix for coordinates = \"motor\"", n, c.nrows()));
        }
        let ci = c
            .clone()
            .try_inverse()
            .ok_or_else(|| Error::invalid("coordinates = \"motor\"", "coupling", "the robot's coupling matrix is singular"))?;
        let map = |rows: &mut Vec<Vec<f64>>| {
            for row in rows.iter_mut() {
                let x = nalgebra::DVector::from_column_slice(row);
                row.copy_from_slice((&ci * x).as_slice());
            }
        };
        for rep in &mut self.reps {
            map(&mut rep.q);
            for v in [&mut rep.r, &mut rep.qd, &mut rep.qdd].into_iter().flatten() {
                map(v);
            }
        }
        if let Some(vq) = self.averaged.as_mut().and_then(|a| a.var_q.as_mut()) {
            let c2 = ci.map(|x| x * x);
            map_with(vq, &c2);
        }
        Ok(())
    }

    /// Reads a run: each path is a CSV file or a folder (all `*.csv` except
    /// `reference.csv`, sorted by name), for a robot with `n` joints.
    pub fn read(paths: &[PathBuf], n: usize) -> Result<Run> {
        Run::read_with(paths, n, None)
    }

    /// [`Run::read`] with N_r for an averaged run (`--repetitions`; else
    /// `run.json` in its folder). A file with `var_tau*` columns is an averaged
    /// run and must be the only file; `repetitions` without variance columns
    /// is an error (N_r of raw repetitions is the number of files).
    pub fn read_with(paths: &[PathBuf], n: usize, repetitions: Option<usize>) -> Result<Run> {
        let files = expand(paths)?;
        let tables = files.iter().map(|f| Table::read(f)).collect::<Result<Vec<_>>>()?;
        Run::from_tables(files, tables, n, repetitions)
    }

    /// A run from parsed tables (see [`Run::read_with`]).
    fn from_tables(files: Vec<PathBuf>, tables: Vec<Table>, n: usize, repetitions: Option<usize>) -> Result<Run> {
        Ok(Run::from_tables_sampled(files, tables, n, repetitions, None)?.0)
    }

    /// [`Run::from_tables`], irregular times resampled when `sampling` is given.
    fn from_tables_sampled(
        files: Vec<PathBuf>,
        tables: Vec<Table>,
        n: usize,
        repetitions: Option<usize>,
        sampling: Option<SamplingOptions>,
    ) -> Result<(Run, Option<super::resample::Sampling>)> {
        if sampling.is_none() {
            return Ok((Run::from_tables_uniform(files, tables, n, repetitions)?, None));
        }
        let has_var = tables.iter().any(|t| t.columns.iter().any(|c| c.starts_with("var_")));
        if has_var {
            let run = Run::from_tables_uniform(files, tables, n, repetitions)?;
            let info = super::resample::resample_run(&mut run.reps.clone(), &run.files, None, usize::MAX)?;
            return Ok((run, Some(info)));
        }
        if let Some(r) = repetitions {
            return Err(Error::invalid(
                files[0].display().to_string(),
                "repetitions",
                format!("repetitions = {r} is for an averaged run (one CSV with var_tau1..var_taun columns); this run has {} raw repetition file(s) and no variance columns", files.len()),
            ));
        }
        let so = sampling.unwrap_or_default();
        let mut reps = tables.iter().map(|t| Repetition::from_table_timed(t, n, true)).collect::<Result<Vec<_>>>()?;
        let info = super::resample::resample_run(&mut reps, &files, so.rate, so.limit)?;
        Ok((Run::new(files, reps)?, Some(info)))
    }

    /// [`Run::from_tables`] with uniform time steps required.
    fn from_tables_uniform(files: Vec<PathBuf>, tables: Vec<Table>, n: usize, repetitions: Option<usize>) -> Result<Run> {
        let has_var = |t: &Table| t.columns.iter().any(|c| c.starts_with("var_"));
        if let Some(i) = tables.iter().position(has_var) {
            let t = &tables[i];
            if tables.len() > 1 {
                return Err(Error::Data {
                    path: t.path.clone(),
                    row: 0,
                    column: t.columns.iter().find(|c| c.starts_with("var_")).cloned().unwrap_or_default(),
                    msg: format!(
                        "variance columns make this file an averaged run (the means over N_r repetitions), but the run has {} files: give the averaged file alone",
                        tables.len()
                    ),
                });
            }
            if t.index("var_tau1").is_none() {
                return Err(Error::Data {
                    path: t.path.clone(),
                    row: 0,
                    column: "var_tau1".into(),
                    msg: format!("an averaged run needs the torque variances var_tau1..var_tau{n}"),
                });
            }
            let mean = Repetition::from_table(t, n)?;
            let pick = |idx: &[usize]| -> Vec<Vec<f64>> { t.rows.iter().map(|r| idx.iter().map(|&i| r[i]).collect()).collect() };
            let var_tau = pick(&t.numbered("var_tau", n)?);
            let var_q = if t.index("var_q1").is_some() || t.columns.iter().any(|c| c.starts_with("var_q")) {
                Some(pick(&t.numbered("var_q", n)?))
            } else {
                None
            };
            let nr = match repetitions {
                Some(r) => r,
                None => read_meta(&t.path)?.ok_or_else(|| Error::Data {
                    path: t.path.clone(),
                    row: 0,
                    column: "var_tau1".into(),
                    msg: "an averaged run needs N_r, the number of repetitions the means were taken over (paper 000 eq. 13): give `repetitions = N` or write {\"repetitions\": N} into run.json next to the file".into(),
                })?,
            };
            return Run::averaged(t.path.clone(), mean, var_tau, var_q, nr);
        }
        if let Some(r) = repetitions {
            return Err(Error::invalid(
                files[0].display().to_string(),
                "repetitions",
                format!(
                    "repetitions = {r} is for an averaged run (one CSV with var_tau1..var_taun columns); this run has {} raw repetition file(s) and no variance columns",
                    files.len()
                ),
            ));
        }
        let reps = tables.iter().map(|t| Repetition::from_table(t, n)).collect::<Result<Vec<_>>>()?;
        Run::new(files, reps)
    }

    /// Number of repetitions N_r (for an averaged run: the number the means were taken over).
    pub fn n_reps(&self) -> usize {
        self.averaged.as_ref().map_or(self.reps.len(), |a| a.repetitions)
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

fn map_with(rows: &mut [Vec<f64>], m: &nalgebra::DMatrix<f64>) {
    for row in rows.iter_mut() {
        let x = nalgebra::DVector::from_column_slice(row);
        row.copy_from_slice((m * x).as_slice());
    }
}

/// N_r from `run.json` in the folder of `file`, if that file exists.
fn read_meta(file: &Path) -> Result<Option<usize>> {
    let Some(p) = file.parent().map(|d| d.join("run.json")) else {
        return Ok(None);
    };
    if !p.exists() {
        return Ok(None);
    }
    let text = crate::io::read_to_string(&p)?;
    let m: RunMeta = serde_json::from_str(&text).map_err(|e| Error::parse(&p, e.to_string()))?;
    let _ = m.source;
    Ok(m.repetitions)
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
