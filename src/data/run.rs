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

use crate::error::{Error, Result};
use crate::io::Table;
use crate::robot::Robot;
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
    /// increase strictly (the caller resamples them, [`super::resample`]).
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
                    "the run logs motor currents cur1..cur{n} but no torques tau1..tau{n}: currents need the robot's torque constants (idexp identify --torque-from current|auto with torque_constant and gear_ratio in the robot file's [[drive]] entries; library: Run::read_drives)"
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
            super::resample::check_increasing(path, &times)?;
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
            _ => Err(Error::invalid("--coordinates", "coordinates", format!("expected joint or motor, found `{s}`"))),
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
                    "variance columns with {repetitions} repetition(s): the sample variance (eq. 7) needs N_r ≥ 2; give the number the means were taken over (--repetitions N or \"repetitions\" in run.json)"
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
                                "expected a positive finite variance, found {x} (a zero variance would give an infinite weight; use --weights joint if some are unknown)"
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
            return Err(Error::dim("coupling matrix for --coordinates motor", n, c.nrows()));
        }
        let ci = c
            .clone()
            .try_inverse()
            .ok_or_else(|| Error::invalid("--coordinates motor", "coupling", "the robot's coupling matrix is singular"))?;
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

    /// [`Run::read_with`] for the robot `robot`, with the joint torques taken
    /// from the columns `from` says (see the module documentation): currents
    /// `cur*` are converted by each drive's s·k_t·N; when torques and
    /// currents are both logged and the drives have torque constants, they
    /// must agree within `tolerance` (relative RMS per file and joint).
    /// Returns the run and what was done.
    pub fn read_drives(paths: &[PathBuf], robot: &Robot, repetitions: Option<usize>, from: TorqueFrom, tolerance: f64) -> Result<(Run, TorqueSource)> {
        let (run, src, _) = Run::read_drives_sampled(paths, robot, repetitions, from, tolerance, None)?;
        Ok((run, src))
    }

    /// [`Run::read_drives`] with irregular time stamps accepted when
    /// `sampling` is given: every repetition is then resampled to a uniform
    /// grid at `sampling.rate` Hz (default: the inverse median logged step;
    /// [`super::resample`]), at most `sampling.limit` samples each. Returns
    /// what was done with the time stamps too.
    pub fn read_drives_sampled(
        paths: &[PathBuf],
        robot: &Robot,
        repetitions: Option<usize>,
        from: TorqueFrom,
        tolerance: f64,
        sampling: Option<SamplingOptions>,
    ) -> Result<(Run, TorqueSource, Option<super::resample::Sampling>)> {
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(Error::invalid(
                "identify",
                "--current-tolerance",
                format!("expected a positive relative tolerance, found {tolerance}"),
            ));
        }
        let n = robot.dof();
        let files = expand(paths)?;
        let mut tables = files.iter().map(|f| Table::read(f)).collect::<Result<Vec<_>>>()?;
        let has = |t: &Table, p: &str| (1..=n).any(|i| t.index(&format!("{p}{i}")).is_some());
        let has_tau = has(&tables[0], "tau");
        let has_cur = has(&tables[0], "cur");
        for t in &tables[1..] {
            for (p, want) in [("tau", has_tau), ("cur", has_cur)] {
                if has(t, p) != want {
                    return Err(Error::Data {
                        path: t.path.clone(),
                        row: 0,
                        column: format!("{p}1"),
                        msg: format!(
                            "{p}* columns present in one repetition but not in {}: use the same columns in all files",
                            tables[0].path.display()
                        ),
                    });
                }
            }
        }
        let use_current = match from {
            TorqueFrom::Torque => false,
            TorqueFrom::Current => true,
            TorqueFrom::Auto => !has_tau,
        };
        if use_current && !has_cur {
            return Err(Error::Data {
                path: tables[0].path.clone(),
                row: 0,
                column: "cur1".into(),
                msg: format!("--torque-from current, but the run has no current columns cur1..cur{n}"),
            });
        }
        if !use_current && !has_tau {
            return Err(Error::Data {
                path: tables[0].path.clone(),
                row: 0,
                column: "tau1".into(),
                msg: format!("--torque-from torque, but the run has no torque columns tau1..tau{n} (it logs currents: use --torque-from current or auto)"),
            });
        }
        let scale: Vec<Option<f64>> = robot.drives.iter().map(|d| d.torque_per_ampere()).collect();
        let all_kt = scale.iter().all(|s| s.is_some());
        let mut note = String::new();
        if has_cur && (use_current || all_kt) {
            if let Some(j) = scale.iter().position(|s| s.is_none()) {
                return Err(Error::Data {
                    path: tables[0].path.clone(),
                    row: 0,
                    column: format!("cur{}", j + 1),
                    msg: format!(
                        "a current column for joint `{}`, but its drive has no torque_constant in the robot file {}: add torque_constant = k_t (N·m/A, motor side) and gear_ratio to its [[drive]] entry (τ = current_sign·k_t·N·i)",
                        robot.joints[j].name, robot.source
                    ),
                });
            }
        } else if has_cur {
            note = "currents logged but not used or checked: the robot file gives no torque_constant".into();
        }
        let scale: Vec<f64> = scale.iter().map(|s| s.unwrap_or(f64::NAN)).collect();
        let mut agreement = None;
        if has_cur && all_kt {
            let mut worst = vec![0.0_f64; n];
            for t in &mut tables {
                let icur = t.numbered("cur", n)?;
                if has_tau {
                    let itau = t.numbered("tau", n)?;
                    for j in 0..n {
                        let (mut d2, mut t2) = (0.0, 0.0);
                        for r in &t.rows {
                            let tc = scale[j] * r[icur[j]];
                            d2 += (tc - r[itau[j]]).powi(2);
                            t2 += r[itau[j]].powi(2);
                        }
                        let m = t.rows.len() as f64;
                        let (drms, trms) = ((d2 / m).sqrt(), (t2 / m).sqrt());
                        let rel = if trms > 0.0 {
                            drms / trms
                        } else if drms > 0.0 {
                            f64::INFINITY
                        } else {
                            0.0
                        };
                        if rel > tolerance {
                            return Err(Error::Data {
                                path: t.path.clone(),
                                row: 0,
                                column: format!("cur{}", j + 1),
                                msg: format!(
                                    "joint `{}`: the torque from the currents (current_sign·k_t·N = {} N·m/A) differs from tau{} by RMS {drms:.4e} N·m, {:.2} % of the torque RMS {trms:.4e} N·m, above the tolerance {:.2} % (--current-tolerance {tolerance}): check torque_constant, gear_ratio and current_sign of the drive, or the logs",
                                    robot.joints[j].name,
                                    scale[j],
                                    j + 1,
                                    100.0 * rel,
                                    100.0 * tolerance
                                ),
                            });
                        }
                        worst[j] = worst[j].max(rel);
                    }
                }
                if use_current {
                    currents_to_torques(t, &icur, &scale, n)?;
                }
            }
            if has_tau {
                agreement = Some(worst);
            }
        }
        let (run, sampled) = Run::from_tables_sampled(files, tables, n, repetitions, sampling)?;
        Ok((
            run,
            TorqueSource {
                from: if use_current { "current" } else { "torque" }.into(),
                torque_per_ampere: if use_current || all_kt { Some(scale) } else { None },
                agreement,
                tolerance,
                note,
            },
            sampled,
        ))
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
                    msg: "an averaged run needs N_r, the number of repetitions the means were taken over (paper 000 eq. 13): pass --repetitions N or write {\"repetitions\": N} into run.json next to the file".into(),
                })?,
            };
            return Run::averaged(t.path.clone(), mean, var_tau, var_q, nr);
        }
        if let Some(r) = repetitions {
            return Err(Error::invalid(
                files[0].display().to_string(),
                "--repetitions",
                format!(
                    "--repetitions {r} is for an averaged run (one CSV with var_tau1..var_taun columns); this run has {} raw repetition file(s) and no variance columns",
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

/// Replaces the current columns `cur*` (and `var_cur*`) of `t` by the torque
/// columns `tau*` (`var_tau*`) they give with `scale` = s·k_t·N per joint.
fn currents_to_torques(t: &mut Table, icur: &[usize], scale: &[f64], n: usize) -> Result<()> {
    let ivar = if (1..=n).any(|i| t.index(&format!("var_cur{i}")).is_some()) {
        Some(t.numbered("var_cur", n)?)
    } else {
        None
    };
    let mut drop: Vec<usize> = (1..=n).filter_map(|i| t.index(&format!("tau{i}"))).collect();
    drop.extend((1..=n).filter_map(|i| t.index(&format!("var_tau{i}"))).filter(|_| ivar.is_some()));
    let mut columns: Vec<String> = Vec::new();
    let mut src: Vec<(usize, f64, bool)> = Vec::new(); // (column, factor, squared)
    for (c, name) in t.columns.iter().enumerate() {
        if drop.contains(&c) {
            continue;
        }
        if let Some(j) = icur.iter().position(|&i| i == c) {
            columns.push(format!("tau{}", j + 1));
            src.push((c, scale[j], false));
        } else if let Some(j) = ivar.as_ref().and_then(|v| v.iter().position(|&i| i == c)) {
            columns.push(format!("var_tau{}", j + 1));
            src.push((c, scale[j] * scale[j], true));
        } else {
            columns.push(name.clone());
            src.push((c, 1.0, false));
        }
    }
    let rows = t.rows.iter().map(|r| src.iter().map(|&(c, f, _)| f * r[c]).collect()).collect();
    t.columns = columns;
    t.rows = rows;
    Ok(())
}

/// Where the joint torques of a run come from (`idexp identify --torque-from`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TorqueFrom {
    /// Torques `tau*` when logged, else currents `cur*`.
    #[default]
    Auto,
    /// The torque columns.
    Torque,
    /// The current columns, converted with the robot's drives.
    Current,
}

impl std::str::FromStr for TorqueFrom {
    type Err = Error;
    fn from_str(s: &str) -> Result<TorqueFrom> {
        match s {
            "auto" => Ok(TorqueFrom::Auto),
            "torque" => Ok(TorqueFrom::Torque),
            "current" => Ok(TorqueFrom::Current),
            _ => Err(Error::invalid(
                "--torque-from",
                "torque_from",
                format!("expected auto, torque or current, found `{s}`"),
            )),
        }
    }
}

impl std::fmt::Display for TorqueFrom {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            TorqueFrom::Auto => "auto",
            TorqueFrom::Torque => "torque",
            TorqueFrom::Current => "current",
        })
    }
}

/// Default tolerance between logged torques and the torques of logged
/// currents: 5 % relative RMS per file and joint.
pub const CURRENT_TOLERANCE: f64 = 0.05;

/// How [`Run::read_drives`] obtained the joint torques.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TorqueSource {
    /// `torque` or `current`.
    pub from: String,
    /// Per joint s·k_t·N (N·m/A joint side), when the drives give it.
    pub torque_per_ampere: Option<Vec<f64>>,
    /// Per joint, the largest relative RMS difference between logged torques
    /// and the currents' torques over the files, when both were logged.
    pub agreement: Option<Vec<f64>>,
    /// The tolerance applied to `agreement`.
    pub tolerance: f64,
    /// Anything else worth saying (currents ignored, ...).
    pub note: String,
}

impl TorqueSource {
    /// One line for reports.
    pub fn text(&self) -> String {
        let mut s = format!(
            "joint torques from the {} columns",
            if self.from == "current" { "current (cur*)" } else { "torque (tau*)" }
        );
        if let (Some(k), true) = (&self.torque_per_ampere, self.from == "current") {
            s += &format!(
                ", τ = s·k_t·N·i with s·k_t·N = [{}] N·m/A",
                k.iter().map(|v| format!("{v}")).collect::<Vec<_>>().join(", ")
            );
        }
        if let Some(a) = &self.agreement {
            s += &format!(
                "; torques and currents agree within [{}] % (tolerance {} %)",
                a.iter().map(|v| format!("{:.2}", 100.0 * v)).collect::<Vec<_>>().join(", "),
                100.0 * self.tolerance
            );
        }
        if !self.note.is_empty() {
            s += &format!("; {}", self.note);
        }
        s
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
