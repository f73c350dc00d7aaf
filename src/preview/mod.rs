//! The interactive 3D preview of a trajectory: `preview.html`, one
//! self-contained page (three.js and the data embedded) that opens offline
//! from the file system.
//!
//! The page shows the robot's collision geometry exactly as idexp checks it
//! (the convex parts of [`crate::robot::collision`], grown by their padding;
//! [`geometry`]), the floor, the design's obstacles and Cartesian workspace
//! volumes, posed along the trajectory, with the end-effector path, the
//! closest self pair and the closest environment pair at every instant
//! (witness points and distance), the worst instants one click away, and the
//! joint positions and velocities against their limits.
//!
//! **What is computed here, not in the browser.** Every pose and distance
//! comes from the library: the trajectory's samples (the 1 kHz rows of
//! `trajectory.csv`) are scanned in full (a delivered trajectory's rows of
//! period s ≥ 2 repeat period 1's rows at the same phase bit for bit, as in
//! `trajectory.csv`, and are scanned once), and the page holds
//!
//! - display frames every `rate/fps` rows (30 frames/s by default), each a
//!   row of the trajectory: link poses (f32), q and q̇, and per class (self,
//!   world) the closest pair with its witness points and its exact capped
//!   distance ([`CollisionScene::closest_where`], the query behind the
//!   report's margins and safety check, cap = margin + 1 m as the report's);
//! - the worst rows of the whole trajectory as frames of their own: the
//!   closest self pair and the closest environment pair over every row
//!   ([`CollisionScene::pair_series`], exact wherever a row can be the
//!   minimum, as the report's verification), the smallest position and
//!   velocity margins;
//! - the report's own worst instants when the trajectory is an `idexp
//!   excite` result: the least self and world distances of `report.json`
//!   (found on one period at the verification rate; period 1 of the
//!   delivered trajectory starts after the lead-in), each as a frame
//!   evaluated at that time.
//!
//! The page exposes its state to scripts and tests: `window.idexpState` and
//! its JSON copy in the element `#idexp-state` (time, frame, segment, the
//! closest pairs and their distances, q, q̇); the URL hash `#t=12.5` sets
//! the time (the frame at or nearest it), `#hide=robot` hides the robot.

pub mod geometry;
mod page;
mod sources;

pub use sources::{read_rows, report_instants, write_for_folder, write_for_result, write_for_trajectory};

use crate::error::{Error, Result};
use crate::excitation::constraints::JointLimitSpec;
use crate::excitation::design::ExciteDesign;
use crate::robot::cartesian::CartesianConstraint;
use crate::robot::collision::{CollisionScene, CollisionSpec, DistanceSeries, PairClass, Proximity};
use crate::robot::kinematics::{forward_kinematics, Kin};
use crate::robot::model::Robot;
use crate::trajectory::lead::{Delivered, LEAD_IN, LEAD_OUT};
use nalgebra::{Isometry3, Rotation3, UnitQuaternion};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Options of the preview.
#[derive(Debug, Clone, PartialEq)]
pub struct PreviewOptions {
    /// Display frames per second of trajectory time (default 30): every
    /// round(rate/fps)-th row becomes a frame.
    pub fps: f64,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions { fps: 30.0 }
    }
}

/// The samples the page is built from.
#[derive(Debug, Clone)]
pub enum Motion {
    /// A delivered excitation trajectory sampled at `rate` Hz, t_k = k/rate
    /// (the rows of `trajectory.csv`), evaluated exactly at any other time.
    Delivered {
        /// The trajectory.
        delivered: Delivered,
        /// Sample rate (Hz).
        rate: f64,
    },
    /// Rows of a trajectory CSV: times, positions and velocities (n per row,
    /// row after row) and, when the file has one, the `segment` column.
    Rows {
        /// Times (s), increasing.
        t: Vec<f64>,
        /// Positions, `n` per row.
        q: Vec<f64>,
        /// Velocities, `n` per row.
        qd: Vec<f64>,
        /// Segment per row (0 lead-in, k period k, −1 lead-out), if known.
        segment: Option<Vec<i64>>,
    },
}

impl Motion {
    /// Number of rows.
    pub fn len(&self, n: usize) -> usize {
        match self {
            Motion::Delivered { delivered, rate } => (delivered.duration() * rate - 1e-6).ceil().max(0.0) as usize + 1,
            Motion::Rows { q, .. } => q.len().checked_div(n).unwrap_or(0),
        }
    }

    /// True without rows.
    pub fn is_empty(&self, n: usize) -> bool {
        self.len(n) == 0
    }

    /// Row `k` into `q`, `qd`; returns (t, segment or `i64::MIN` when unknown).
    fn row(&self, k: usize, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) -> (f64, i64) {
        match self {
            Motion::Delivered { delivered, rate } => {
                // a row of period s ≥ 2 takes the state of period 1's row at
                // the same phase, as trajectory.csv does
                let (seg, src) = delivered.rows(*rate).row(delivered, k);
                delivered.eval(src as f64 / rate, q, qd, qdd);
                (k as f64 / rate, seg)
            }
            Motion::Rows { t, q: qs, qd: qds, segment } => {
                let n = q.len();
                q.copy_from_slice(&qs[k * n..(k + 1) * n]);
                qd.copy_from_slice(&qds[k * n..(k + 1) * n]);
                (t[k], segment.as_ref().map_or(i64::MIN, |s| s[k]))
            }
        }
    }

    /// True when row `k` repeats the state of an earlier row (a row of a
    /// delivered trajectory's period s ≥ 2): the scan for the first row of
    /// least distance or margin skips it.
    fn repeats(&self, k: usize) -> bool {
        match self {
            Motion::Delivered { delivered, rate } => delivered.rows(*rate).row(delivered, k).1 != k,
            Motion::Rows { .. } => false,
        }
    }

    /// The state at time `t`: exact for a delivered trajectory, else the
    /// nearest row. Returns (time of the state, segment).
    fn at(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) -> (f64, i64) {
        match self {
            Motion::Delivered { delivered, .. } => (t, delivered.eval(t, q, qd, qdd)),
            Motion::Rows { t: ts, .. } => self.row(nearest(ts, t), q, qd, qdd),
        }
    }

    /// The segments as time intervals: (start, end, segment).
    fn segments(&self, n: usize) -> Vec<(f64, f64, i64)> {
        match self {
            Motion::Delivered { delivered: d, .. } => {
                let mut v = Vec::new();
                if d.lead_in_duration() > 0.0 {
                    v.push((0.0, d.lead_in_duration(), LEAD_IN));
                }
                for k in 0..d.periods {
                    let t0 = d.periodic_start() + k as f64 * crate::trajectory::Motion::duration(&d.periodic);
                    v.push((t0, t0 + crate::trajectory::Motion::duration(&d.periodic), k as i64 + 1));
                }
                if d.lead_out_duration() > 0.0 {
                    v.push((d.periodic_end(), d.duration(), LEAD_OUT));
                }
                v
            }
            Motion::Rows { t, segment, .. } => {
                let Some(seg) = segment else {
                    return Vec::new();
                };
                let mut v: Vec<(f64, f64, i64)> = Vec::new();
                for k in 0..self.len(n) {
                    match v.last_mut() {
                        Some(last) if last.2 == seg[k] => last.1 = t[k],
                        _ => {
                            if let Some(last) = v.last_mut() {
                                last.1 = t[k];
                            }
                            v.push((t[k], t[k], seg[k]));
                        }
                    }
                }
                v
            }
        }
    }
}

/// A worst instant reported by `report.json` (the least distance of a
/// class over the design's verification grid), to be shown as a frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReportInstant {
    /// `self` or `world`.
    pub class: String,
    /// The pair as the report names it (`self: a – b`).
    pub pair: String,
    /// The distance the report gives (m).
    pub distance: f64,
    /// Time in the trajectory (s): the lead-in's duration plus the time
    /// within the period the report gives.
    pub t: f64,
}

/// What the page shows besides the motion.
#[derive(Debug, Clone)]
pub struct Setup {
    /// Title of the page (the design or file name).
    pub title: String,
    /// The robot.
    pub robot: Robot,
    /// The collision scene the distances are computed in (`None`: nothing
    /// to check; the page then draws the skeleton only).
    pub scene: Option<CollisionScene>,
    /// Cartesian workspace constraints of the design (drawn as volumes).
    pub workspace: Vec<CartesianConstraint>,
    /// Joint limits the trajectory was designed under (drawn as bands).
    pub limits: JointLimitSpec,
    /// What the limits are (`design` or `robot file`).
    pub limits_source: String,
    /// Worst instants of `report.json`, if any.
    pub report: Vec<ReportInstant>,
}

impl Setup {
    /// The setup of an excitation design: its collision scene (the design's
    /// `[collision]`; when that is off, the robot's geometry, floor and
    /// obstacles without a margin, as the safety check after the run), its
    /// workspace and joint limits.
    pub fn from_design(d: &ExciteDesign, robot: Robot, ctx: &str) -> Result<Setup> {
        let (limits, _) = crate::excitation::limits::resolve(&d.limits, &robot, &d.robot, ctx)?;
        let spec = if d.collision.enabled {
            d.collision.clone()
        } else {
            CollisionSpec {
                enabled: true,
                margin: 0.0,
                ..d.collision.clone()
            }
        };
        let scene = CollisionScene::new(&robot, &spec, Path::new(""), ctx)?;
        Ok(Setup {
            title: d.name.clone(),
            robot,
            scene,
            workspace: d.workspace.clone(),
            limits,
            limits_source: "design".into(),
            report: Vec::new(),
        })
    }

    /// The setup of a robot alone: its collision geometry and the floor
    /// (no margin), its joint position and velocity limits.
    pub fn from_robot(robot: Robot, title: &str) -> Result<Setup> {
        let spec = CollisionSpec {
            margin: 0.0,
            ..CollisionSpec::default()
        };
        let scene = CollisionScene::new(&robot, &spec, Path::new(""), title)?;
        let limits = JointLimitSpec {
            position: robot.joints.iter().map(|j| [j.limits.lower, j.limits.upper]).collect(),
            velocity: robot.joints.iter().map(|j| j.limits.velocity).collect(),
            acceleration: vec![f64::INFINITY; robot.dof()],
            torque: vec![f64::INFINITY; robot.dof()],
        };
        Ok(Setup {
            title: title.to_string(),
            robot,
            scene,
            workspace: Vec::new(),
            limits,
            limits_source: "robot file".into(),
            report: Vec::new(),
        })
    }
}

/// The closest pair of one class at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// Index into the scene's pairs.
    pub pair: usize,
    /// Distance, witness points and normal.
    pub proximity: Proximity,
}

/// A worst instant of the trajectory (a frame of its own on the page).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Instant {
    /// What it is the worst of.
    pub label: String,
    /// Time (s).
    pub t: f64,
    /// Index of its frame.
    pub frame: usize,
    /// One line: the pair or joint and the value.
    pub detail: String,
    /// The value (m, rad or rad/s).
    pub value: f64,
}

/// What the page shows, before encoding.
#[derive(Debug, Clone)]
pub struct Preview {
    /// Frame times (s).
    pub t: Vec<f64>,
    /// Segment per frame (`i64::MIN`: unknown).
    pub segment: Vec<i64>,
    /// q per frame (n each).
    pub q: Vec<f64>,
    /// q̇ per frame (n each).
    pub qd: Vec<f64>,
    /// Link poses per frame: n × (x, y, z, qx, qy, qz, qw).
    pub link_poses: Vec<f32>,
    /// End-effector position per frame.
    pub ee: Vec<f32>,
    /// Closest self pair per frame.
    pub closest_self: Vec<Option<Closest>>,
    /// Closest world pair per frame.
    pub closest_world: Vec<Option<Closest>>,
    /// The worst instants.
    pub instants: Vec<Instant>,
    /// Rows scanned.
    pub rows: usize,
    /// Cap of the distances (m): farther pairs are not resolved.
    pub cap: f64,
    segments: Vec<(f64, f64, i64)>,
}

impl Preview {
    /// The frame of an instant of the trajectory at time `t` (the nearest frame).
    pub fn frame_at(&self, t: f64) -> usize {
        nearest(&self.t, t)
    }
}

/// The index of the time in `ts` (increasing) nearest `t`, the earlier on a tie.
fn nearest(ts: &[f64], t: f64) -> usize {
    let k = ts.partition_point(|&x| x < t);
    match (k.checked_sub(1), ts.get(k)) {
        (Some(a), Some(&b)) if (t - ts[a]) <= (b - t) => a,
        (Some(a), None) => a,
        _ => k,
    }
}

fn iso_of(kin: &Kin<f64>, l: usize) -> Isometry3<f64> {
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(kin.wrot[l]));
    Isometry3::from_parts(nalgebra::Translation3::from(kin.wpos[l]), rot)
}

/// The least value of a scan and where: (value, row, index) with the first
/// row of least value kept on ties.
type Least = Option<(f64, usize, usize)>;

fn keep_least(a: Least, b: Least) -> Least {
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.0 < x.0 || (y.0 == x.0 && y.1 < x.1) { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

/// The worst rows of a chunk: least self distance, least world distance
/// (value, row, pair), least position margin and least velocity margin
/// (value, row, joint).
#[derive(Debug, Clone, Copy, Default)]
struct Worst {
    dist: [Least; 2],
    pos: Least,
    vel: Least,
}

impl Worst {
    fn merge(self, o: Worst) -> Worst {
        Worst {
            dist: [keep_least(self.dist[0], o.dist[0]), keep_least(self.dist[1], o.dist[1])],
            pos: keep_least(self.pos, o.pos),
            vel: keep_least(self.vel, o.vel),
        }
    }
}

const CHUNK: usize = 4096;

/// Scans every row of the motion: the least distance per class (exact:
/// [`CollisionScene::pair_series`] per pair and chunk) and the least joint
/// margins.
fn scan(setup: &Setup, motion: &Motion, cap: f64) -> Worst {
    let robot = &setup.robot;
    let n = robot.dof();
    let rows = motion.len(n);
    let chunks: Vec<usize> = (0..rows).step_by(CHUNK).collect();
    chunks
        .par_iter()
        .map(|&k0| {
            let k1 = (k0 + CHUNK).min(rows);
            let mut kin = Kin::new(n);
            let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            let mut w = Worst::default();
            let mut poses: Vec<Vec<Isometry3<f64>>> = Vec::with_capacity(k1 - k0);
            let mut row_of = Vec::with_capacity(k1 - k0);
            for k in (k0..k1).filter(|&k| !motion.repeats(k)) {
                motion.row(k, &mut q, &mut qd, &mut qdd);
                row_of.push(k);
                for j in 0..n {
                    let [lo, hi] = setup.limits.position[j];
                    let m = (q[j] - lo).min(hi - q[j]);
                    if m.is_finite() {
                        w.pos = keep_least(w.pos, Some((m, k, j)));
                    }
                    let m = setup.limits.velocity[j] - qd[j].abs();
                    if m.is_finite() {
                        w.vel = keep_least(w.vel, Some((m, k, j)));
                    }
                }
                if let Some(sc) = &setup.scene {
                    forward_kinematics(robot, &q, &mut kin);
                    let mut x = Vec::new();
                    sc.poses(&kin, &mut x);
                    poses.push(x);
                }
            }
            if let Some(sc) = &setup.scene {
                let mut series = DistanceSeries::default();
                for (k, p) in sc.pairs.iter().enumerate() {
                    sc.pair_series(k, &poses, cap, false, &mut series);
                    if let Some((g, v)) = series.argmin() {
                        if v < cap {
                            let c = usize::from(p.class == PairClass::World);
                            w.dist[c] = keep_least(w.dist[c], Some((v, row_of[g], k)));
                        }
                    }
                }
            }
            w
        })
        .reduce(Worst::default, Worst::merge)
}

/// One display frame.
struct Frame {
    t: f64,
    segment: i64,
    q: Vec<f64>,
    qd: Vec<f64>,
}

/// Builds what the page shows: scans every row, picks the display frames
/// and the worst instants, and computes each frame's poses and closest pairs.
pub fn build(setup: &Setup, motion: &Motion, opts: &PreviewOptions) -> Result<Preview> {
    let robot = &setup.robot;
    let n = robot.dof();
    let rows = motion.len(n);
    if rows == 0 {
        return Err(Error::invalid(&setup.title, "trajectory", "has no rows"));
    }
    if !(opts.fps.is_finite() && opts.fps > 0.0 && opts.fps <= 1000.0) {
        return Err(Error::invalid(&setup.title, "fps", format!("{} must be in (0, 1000] frames/s", opts.fps)));
    }
    let cap = setup.scene.as_ref().map_or(1.0, |s| s.margin + 1.0);
    let worst = scan(setup, motion, cap);
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    // the display rows: every `step`-th row of the trajectory and the last
    let (t0, _) = motion.row(0, &mut q, &mut qd, &mut qdd);
    let (t_end, _) = motion.row(rows - 1, &mut q, &mut qd, &mut qdd);
    let rate = if rows > 1 { (rows - 1) as f64 / (t_end - t0) } else { 1.0 };
    let step = ((rate / opts.fps).round() as usize).max(1);
    let mut picks: Vec<usize> = (0..rows).step_by(step).collect();
    if picks.last() != Some(&(rows - 1)) {
        picks.push(rows - 1);
    }
    let worst_rows: Vec<usize> = worst.dist.iter().chain([&worst.pos, &worst.vel]).filter_map(|w| w.map(|x| x.1)).collect();
    picks.extend(&worst_rows);
    picks.sort_unstable();
    picks.dedup();
    let mut frames: Vec<Frame> = picks
        .iter()
        .map(|&k| {
            let (t, segment) = motion.row(k, &mut q, &mut qd, &mut qdd);
            Frame {
                t,
                segment,
                q: q.clone(),
                qd: qd.clone(),
            }
        })
        .collect();
    // the report's instants, evaluated at their own time
    for ri in &setup.report {
        let (t, segment) = motion.at(ri.t, &mut q, &mut qd, &mut qdd);
        let at = frames.partition_point(|f| f.t < t);
        if frames.get(at).is_some_and(|f| f.t == t) {
            continue;
        }
        frames.insert(
            at,
            Frame {
                t,
                segment,
                q: q.clone(),
                qd: qd.clone(),
            },
        );
    }
    let ee = robot.end_effector();
    struct Computed {
        poses: Vec<f32>,
        ee: [f32; 3],
        closest: [Option<Closest>; 2],
    }
    let computed: Vec<Computed> = frames
        .par_iter()
        .map_init(
            || (Kin::new(n), Vec::new()),
            |(kin, x), f| {
                forward_kinematics(robot, &f.q, kin);
                let mut poses = Vec::with_capacity(7 * n);
                for l in 0..n {
                    let iso = iso_of(kin, l);
                    let (p, r) = (iso.translation.vector, iso.rotation.coords);
                    poses.extend([p.x, p.y, p.z, r.x, r.y, r.z, r.w].map(|v| v as f32));
                }
                let e = match ee.link {
                    None => ee.placement.translation.vector,
                    Some(l) => kin.wpos[l] + kin.wrot[l] * ee.placement.translation.vector,
                };
                let mut closest = [None, None];
                if let Some(sc) = &setup.scene {
                    sc.poses(kin, x);
                    for (c, class) in [PairClass::SelfCollision, PairClass::World].into_iter().enumerate() {
                        closest[c] = sc
                            .closest_where(x, cap, |p| p.class == class)
                            .map(|(pair, proximity)| Closest { pair, proximity });
                    }
                }
                Computed {
                    poses,
                    ee: [e.x as f32, e.y as f32, e.z as f32],
                    closest,
                }
            },
        )
        .collect();
    let mut pv = Preview {
        t: frames.iter().map(|f| f.t).collect(),
        segment: frames.iter().map(|f| f.segment).collect(),
        q: frames.iter().flat_map(|f| f.q.iter().copied()).collect(),
        qd: frames.iter().flat_map(|f| f.qd.iter().copied()).collect(),
        link_poses: computed.iter().flat_map(|c| c.poses.iter().copied()).collect(),
        ee: computed.iter().flat_map(|c| c.ee).collect(),
        closest_self: computed.iter().map(|c| c.closest[0]).collect(),
        closest_world: computed.iter().map(|c| c.closest[1]).collect(),
        instants: Vec::new(),
        rows,
        cap,
        segments: motion.segments(n),
    };
    // the worst instants, by the frame of their row
    let row_t = |k: usize| {
        let mut q = vec![0.0; n];
        let (mut qd, mut qdd) = (q.clone(), q.clone());
        motion.row(k, &mut q, &mut qd, &mut qdd).0
    };
    let joint = |j: usize| format!("q{} ({})", j + 1, robot.joints[j].name);
    if let Some(sc) = &setup.scene {
        for (c, (label, what)) in [("closest self pair", "self"), ("closest to the floor and cell", "world")].iter().enumerate() {
            if let Some((v, k, pair)) = worst.dist[c] {
                let t = row_t(k);
                pv.instants.push(Instant {
                    label: label.to_string(),
                    t,
                    frame: pv.frame_at(t),
                    detail: format!("{}: {:.4} m (every row scanned: {what} minimum)", sc.pairs[pair].label(), v),
                    value: v,
                });
            }
        }
    }
    for (w, label, unit) in [
        (&worst.pos, "smallest position margin", "rad"),
        (&worst.vel, "smallest velocity margin", "rad/s"),
    ] {
        if let Some((v, k, j)) = *w {
            let t = row_t(k);
            pv.instants.push(Instant {
                label: label.to_string(),
                t,
                frame: pv.frame_at(t),
                detail: format!("{}: {:.4} {unit} from its {} limit", joint(j), v, setup.limits_source),
                value: v,
            });
        }
    }
    for ri in &setup.report {
        let (t, _) = motion.at(ri.t, &mut q, &mut qd, &mut qdd);
        pv.instants.push(Instant {
            label: format!("report.json: least {} distance", ri.class),
            t,
            frame: pv.frame_at(t),
            detail: format!("{}: {:.6} m (one period on the verification grid)", ri.pair, ri.distance),
            value: ri.distance,
        });
    }
    Ok(pv)
}

/// Summary of a written page.
#[derive(Debug, Clone, Serialize)]
pub struct Written {
    /// The page.
    pub path: PathBuf,
    /// Its size (bytes).
    pub bytes: usize,
    /// Display frames.
    pub frames: usize,
    /// Trajectory rows scanned.
    pub rows: usize,
}

/// Builds and writes `path` (atomically).
pub fn write(setup: &Setup, motion: &Motion, opts: &PreviewOptions, path: &Path) -> Result<Written> {
    let pv = build(setup, motion, opts)?;
    let html = page::html(setup, &pv)?;
    crate::io::write_atomic(path, html.as_bytes())?;
    Ok(Written {
        path: path.to_path_buf(),
        bytes: html.len(),
        frames: pv.t.len(),
        rows: pv.rows,
    })
}
