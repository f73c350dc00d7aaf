//! Runs of motor currents: a run read for a robot's drives
//! ([`Run::read_drives`]), the currents converted to joint torques by each
//! drive's s·k_t·N and checked against logged torques ([`TorqueFrom`],
//! [`TorqueSource`]).

use super::{expand, Run, SamplingOptions};
use crate::error::{Error, Result};
use crate::io::Table;
use crate::robot::Robot;
use std::path::PathBuf;

impl Run {
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
    /// [`crate::data::resample`]), at most `sampling.limit` samples each. Returns
    /// what was done with the time stamps too.
    pub fn read_drives_sampled(
        paths: &[PathBuf],
        robot: &Robot,
        repetitions: Option<usize>,
        from: TorqueFrom,
        tolerance: f64,
        sampling: Option<SamplingOptions>,
    ) -> Result<(Run, TorqueSource, Option<crate::data::resample::Sampling>)> {
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(Error::invalid(
                "identify",
                "current_tolerance",
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
                msg: format!("torque_from = \"current\", but the run has no current columns cur1..cur{n}"),
            });
        }
        if !use_current && !has_tau {
            return Err(Error::Data {
                path: tables[0].path.clone(),
                row: 0,
                column: "tau1".into(),
                msg: format!(
                    "torque_from = \"torque\", but the run has no torque columns tau1..tau{n} (it logs currents: use torque_from = \"current\" or \"auto\")"
                ),
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
                                    "joint `{}`: the torque from the currents (current_sign·k_t·N = {} N·m/A) differs from tau{} by RMS {drms:.4e} N·m, {:.2} % of the torque RMS {trms:.4e} N·m, above the tolerance {:.2} % (current_tolerance = {tolerance}): check torque_constant, gear_ratio and current_sign of the drive, or the logs",
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
                from: if use_current { TorqueColumns::Current } else { TorqueColumns::Torque },
                torque_per_ampere: if use_current || all_kt { Some(scale) } else { None },
                agreement,
                tolerance,
                note,
            },
            sampled,
        ))
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
                "identify",
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
    /// The columns the torques came from.
    pub from: TorqueColumns,
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

/// The columns joint torques were taken from (`torque` or `current` in files).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TorqueColumns {
    /// The torque columns `tau*`.
    Torque,
    /// The motor currents `cur*`, through the drives' torque constants.
    Current,
}

impl TorqueSource {
    /// Joint torques given as torques (data in memory, no currents).
    pub fn logged_torques() -> TorqueSource {
        TorqueSource {
            from: TorqueColumns::Torque,
            torque_per_ampere: None,
            agreement: None,
            tolerance: crate::data::CURRENT_TOLERANCE,
            note: String::new(),
        }
    }

    /// One line for reports.
    pub fn text(&self) -> String {
        let mut s = format!(
            "joint torques from the {} columns",
            if self.from == TorqueColumns::Current {
                "current (cur*)"
            } else {
                "torque (tau*)"
            }
        );
        if let (Some(k), true) = (&self.torque_per_ampere, self.from == TorqueColumns::Current) {
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
