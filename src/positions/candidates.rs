//! Candidate configurations: a grid or a seeded random sample over chosen
//! joints (the others fixed), or a CSV of configurations; filtered by the
//! joint limits (less a per-joint margin, e.g. the amplitude of a local
//! excitation), by Cartesian workspace constraints at the pose, and by
//! collision: a pose where any checked pair (self, floor, cell obstacles; the
//! same geometry, pairs and margin as the excitation design) is closer than
//! the margin is dropped.

use crate::error::{Error, Result};
use crate::io::Table;
use crate::robot::cartesian::CartesianConstraint;
use crate::robot::{frame_pose, Robot, Workspace};
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// How candidates are generated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum CandidateKind {
    /// Regular grid over the varied joints.
    #[default]
    Grid,
    /// Uniform random sample over the varied joints (seeded).
    Random,
    /// Configurations from a CSV file (columns q1..qn; optional column `cost`).
    File,
}

/// The `[candidates]` section of a design file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CandidateSpec {
    /// grid | random | file.
    #[serde(default)]
    pub kind: CandidateKind,
    /// Varied joints, 1-based (grid, random). Default: all.
    #[serde(default)]
    pub joints: Vec<usize>,
    /// Grid points per varied joint: one number for all or one per varied joint (default 5).
    #[serde(default)]
    pub points: Option<Vec<usize>>,
    /// Sample size (random, default 1000) before filtering.
    #[serde(default)]
    pub count: Option<usize>,
    /// Lower ends of the ranges of the varied joints (default: joint limits less the margin).
    #[serde(default)]
    pub lower: Option<Vec<f64>>,
    /// Upper ends of the ranges of the varied joints.
    #[serde(default)]
    pub upper: Option<Vec<f64>>,
    /// Values of all n joints; the non-varied ones stay there (default: the middle of each joint's range, 0 if unlimited).
    #[serde(default)]
    pub fixed: Option<Vec<f64>>,
    /// CSV of configurations (file), relative to the design file.
    #[serde(default)]
    pub path: Option<PathBuf>,
    /// Cartesian workspace constraints the pose must satisfy.
    #[serde(default)]
    pub workspace: Vec<CartesianConstraint>,
    /// Collision check of every pose (`[candidates.collision]`, the keys of
    /// the excitation design's `[collision]`); on by default when the robot
    /// has collision geometry.
    #[serde(default)]
    pub collision: crate::robot::collision::CollisionSpec,
}

/// Generated candidates.
#[derive(Debug, Clone)]
pub struct Candidates {
    /// Joint values (n each).
    pub q: Vec<Vec<f64>>,
    /// Costs from the CSV `cost` column (None: all 1).
    pub costs: Option<Vec<f64>>,
    /// Configurations generated before filtering.
    pub generated: usize,
    /// Rejected by the joint limits (with margin).
    pub rejected_limits: usize,
    /// Rejected by the workspace constraints.
    pub rejected_workspace: usize,
    /// Rejected because a checked pair is closer than the collision margin.
    pub rejected_collision: usize,
    /// Why, for the first few rejected poses: `candidate 12: self: forearm_link – wrist_2_link at −0.0131 m`.
    pub collision_reasons: Vec<String>,
}

fn range_of(robot: &Robot, j: usize, margin: f64) -> (f64, f64) {
    let l = &robot.joints[j].limits;
    let lo = if l.lower.is_finite() { l.lower + margin } else { -std::f64::consts::PI };
    let hi = if l.upper.is_finite() { l.upper - margin } else { std::f64::consts::PI };
    (lo, hi)
}

impl CandidateSpec {
    /// Generates and filters the candidates. `margin[j]` is kept clear of the
    /// joint limits; `dir` resolves relative paths; `seed` drives the random sample.
    pub fn generate(&self, robot: &Robot, margin: &[f64], seed: u64, dir: &Path, ctx: &str) -> Result<Candidates> {
        let n = robot.dof();
        let bad = |f: &str, m: String| Error::invalid(ctx, format!("candidates.{f}"), m);
        let joints: Vec<usize> = if self.joints.is_empty() { (1..=n).collect() } else { self.joints.clone() };
        for (k, &j) in joints.iter().enumerate() {
            if j == 0 || j > n {
                return Err(bad("joints", format!("joint {j} does not exist: expected 1..={n}")));
            }
            if joints[..k].contains(&j) {
                return Err(bad("joints", format!("joint {j} is listed twice")));
            }
        }
        let nv = joints.len();
        let fixed: Vec<f64> = match &self.fixed {
            Some(f) => {
                if f.len() != n || f.iter().any(|v| !v.is_finite()) {
                    return Err(bad("fixed", format!("expected {n} finite joint values")));
                }
                f.clone()
            }
            None => (0..n)
                .map(|j| {
                    let (lo, hi) = range_of(robot, j, 0.0);
                    let l = &robot.joints[j].limits;
                    if l.lower.is_finite() && l.upper.is_finite() {
                        0.5 * (lo + hi)
                    } else {
                        0.0
                    }
                })
                .collect(),
        };
        let ranges = |which: &Option<Vec<f64>>, name: &str, upper: bool| -> Result<Vec<f64>> {
            match which {
                Some(v) if v.len() == nv && v.iter().all(|x| x.is_finite()) => Ok(v.clone()),
                Some(_) => Err(bad(name, format!("expected {nv} finite values, one per varied joint"))),
                None => Ok(joints
                    .iter()
                    .map(|&j| {
                        let r = range_of(robot, j - 1, margin[j - 1]);
                        if upper {
                            r.1
                        } else {
                            r.0
                        }
                    })
                    .collect()),
            }
        };
        let mut costs = None;
        let raw: Vec<Vec<f64>> = match self.kind {
            CandidateKind::Grid | CandidateKind::Random => {
                let lo = ranges(&self.lower, "lower", false)?;
                let hi = ranges(&self.upper, "upper", true)?;
                for k in 0..nv {
                    if lo[k] > hi[k] {
                        return Err(bad(
                            "lower",
                            format!("joint {}: empty range [{}, {}] (limits less the margin)", joints[k], lo[k], hi[k]),
                        ));
                    }
                }
                if self.kind == CandidateKind::Grid {
                    let pts: Vec<usize> = match &self.points {
                        None => vec![5; nv],
                        Some(v) if v.len() == 1 => vec![v[0]; nv],
                        Some(v) if v.len() == nv => v.clone(),
                        Some(_) => return Err(bad("points", format!("expected one number or {nv} (one per varied joint)"))),
                    };
                    if pts.contains(&0) {
                        return Err(bad("points", "expected at least 1 point per joint".into()));
                    }
                    let total = pts.iter().try_fold(1usize, |a, &k| a.checked_mul(k)).filter(|&t| t <= 2_000_000);
                    let total = total.ok_or_else(|| bad("points", "the grid has more than 2,000,000 points".into()))?;
                    (0..total)
                        .map(|mut idx| {
                            let mut q = fixed.clone();
                            for k in (0..nv).rev() {
                                let i = idx % pts[k];
                                idx /= pts[k];
                                q[joints[k] - 1] = if pts[k] == 1 {
                                    0.5 * (lo[k] + hi[k])
                                } else {
                                    lo[k] + (hi[k] - lo[k]) * i as f64 / (pts[k] - 1) as f64
                                };
                            }
                            q
                        })
                        .collect()
                } else {
                    let count = self.count.unwrap_or(1000);
                    if count == 0 || count > 2_000_000 {
                        return Err(bad("count", "expected 1..=2,000,000".into()));
                    }
                    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
                    (0..count)
                        .map(|_| {
                            let mut q = fixed.clone();
                            for k in 0..nv {
                                q[joints[k] - 1] = if hi[k] > lo[k] { g.random_range(lo[k]..=hi[k]) } else { lo[k] };
                            }
                            q
                        })
                        .collect()
                }
            }
            CandidateKind::File => {
                let p = self.path.as_ref().ok_or_else(|| bad("path", "kind = \"file\" needs a CSV path".into()))?;
                let path = dir.join(p);
                let t = Table::read(&path)?;
                let cols = t.numbered("q", n)?;
                if let Some(ci) = t.index("cost") {
                    let c = t.column(ci);
                    if let Some(r) = c.iter().position(|v| *v <= 0.0) {
                        return Err(Error::Data {
                            path,
                            row: r + 1,
                            column: "cost".into(),
                            msg: "expected a positive cost".into(),
                        });
                    }
                    costs = Some(c);
                }
                t.rows.iter().map(|r| cols.iter().map(|&c| r[c]).collect()).collect()
            }
        };
        // resolve constraints once
        let frames = self
            .workspace
            .iter()
            .enumerate()
            .map(|(k, c)| c.resolve(robot, ctx, &format!("candidates.workspace[{k}]")))
            .collect::<Result<Vec<_>>>()?;
        let scene =
            crate::robot::collision::CollisionScene::new(robot, &self.collision, dir, &format!("{ctx}: candidates.collision"))?.filter(|s| !s.is_empty());
        let mut kin = crate::robot::kinematics::Kin::new(n);
        let (mut rc, mut reasons) = (0, Vec::new());
        let mut ws = Workspace::new(robot);
        let generated = raw.len();
        let (mut rl, mut rw) = (0, 0);
        let mut q_out = Vec::with_capacity(raw.len());
        let mut c_out = Vec::new();
        for (i, q) in raw.into_iter().enumerate() {
            let within = (0..n).all(|j| {
                let l = &robot.joints[j].limits;
                (!l.lower.is_finite() || q[j] >= l.lower + margin[j] - 1e-12) && (!l.upper.is_finite() || q[j] <= l.upper - margin[j] + 1e-12)
            });
            if !within {
                rl += 1;
                continue;
            }
            let inside = self.workspace.iter().zip(&frames).all(|(c, f)| {
                let pose = frame_pose(robot, &mut ws, &q, f);
                c.shape.margin(&pose.translation.vector) >= 0.0
            });
            if !inside {
                rw += 1;
                continue;
            }
            if let Some(sc) = &scene {
                if let Some(w) = sc.worst_at(robot, &mut kin, &q, sc.cap).filter(|w| w.distance < sc.margin) {
                    rc += 1;
                    if reasons.len() < 10 {
                        reasons.push(format!("candidate {}: {} at {:.4} m (margin {} m)", i + 1, w.label, w.distance, sc.margin));
                    }
                    continue;
                }
            }
            if let Some(c) = &costs {
                c_out.push(c[i]);
            }
            q_out.push(q);
        }
        if q_out.is_empty() {
            return Err(Error::invalid(
                ctx,
                "candidates",
                format!(
                    "no candidate left: {generated} generated, {rl} outside the joint limits (less the margin), {rw} outside the workspace, {rc} in collision{}",
                    reasons.first().map(|r| format!(" (e.g. {r})")).unwrap_or_default()
                ),
            ));
        }
        Ok(Candidates {
            q: q_out,
            costs: costs.map(|_| c_out),
            generated,
            rejected_limits: rl,
            rejected_workspace: rw,
            rejected_collision: rc,
            collision_reasons: reasons,
        })
    }
}
