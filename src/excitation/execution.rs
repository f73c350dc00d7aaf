//! `[execution]`: how the designed periodic trajectory is played on the
//! robot, and the delivered trajectory built from it.
//!
//! A rest-to-rest motion (a B-spline, [`crate::trajectory::Ends::RestToRest`])
//! starts and ends at rest at its start pose, the default home: it is played
//! `periods` times back to back without a lead-in or lead-out (leads are
//! built only when `home` is set to another pose). A B-spline with a free
//! start or end pose (`[trajectory] start = "free"`, `end = "free"`) has
//! q0 as its home: a lead-in from q0 at rest to its start, a lead-out from
//! its end (each only where that pose is not home); likewise a given start
//! or end pose (`start = [q1, ..., qn]`, `end = [..]`).
//!
//! By default (`rest_to_rest = true`) the robot starts at rest at the home
//! pose (default: q0), follows a quintic lead-in to the periodic part's
//! state at t = 0 (position, velocity and acceleration matched, so q, q̇, q̈
//! are continuous), plays `periods` periods, and a quintic lead-out brings it
//! back to home at rest ([`crate::trajectory::lead::Delivered`]). Each lead
//! is the shortest on a ladder of durations (from `min_transition`, 5 %
//! steps, at most `max_transition`) that keeps every joint position,
//! velocity, acceleration and torque limit of the design and every Cartesian
//! workspace constraint at every sample of the `check_rate` grid
//! ([`StateCheck`]). The periodic part itself is verified on the same grid by
//! the design's constraints.
//!
//! ```toml
//! [execution]
//! rest_to_rest = true      # false: the periods as designed, starting at speed (periods = 1: one period)
//! home = [0, 0, 0, 0, 0, 0] # default: the trajectory's q0
//! periods = 3              # repetitions of the periodic part (averaging)
//! min_transition = 0.5     # shortest lead-in / lead-out tried (s)
//! max_transition = 60.0    # longest (s)
//! ```

use super::constraints::{frame_point, JointLimitSpec};
use super::Problem;
use crate::error::{Error, Result};
use crate::robot::cartesian::Shape;
use crate::robot::{inverse_dynamics, Frame, Robot, Workspace};
use crate::trajectory::lead::{self, CheckResult, Delivered, State};
use crate::trajectory::{Motion, ShapeMotion};
use serde::{Deserialize, Serialize};

/// `[execution]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExecutionSpec {
    /// Lead-in from home at rest and lead-out back (default true).
    pub rest_to_rest: bool,
    /// Home pose (default: the trajectory's q0).
    pub home: Option<Vec<f64>>,
    /// Periods played (default 3), with or without the leads.
    pub periods: usize,
    /// Shortest lead duration tried (s).
    pub min_transition: f64,
    /// Longest lead duration tried (s).
    pub max_transition: f64,
}

impl Default for ExecutionSpec {
    fn default() -> Self {
        ExecutionSpec {
            rest_to_rest: true,
            home: None,
            periods: 3,
            min_transition: 0.5,
            max_transition: 60.0,
        }
    }
}

impl ExecutionSpec {
    /// Checks the values; `ctx` names the file.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        if self.periods == 0 || self.periods > 1000 {
            return Err(Error::invalid(
                ctx,
                "execution.periods",
                format!("expected 1..=1000 periods, got {}", self.periods),
            ));
        }
        if !(self.min_transition.is_finite() && self.min_transition > 0.0) {
            return Err(Error::invalid(
                ctx,
                "execution.min_transition",
                format!("expected a positive duration in s, got {}", self.min_transition),
            ));
        }
        if !(self.max_transition.is_finite() && self.max_transition >= self.min_transition && self.max_transition <= 3600.0) {
            return Err(Error::invalid(
                ctx,
                "execution.max_transition",
                format!(
                    "expected min_transition ({}) ≤ max_transition ≤ 3600 s, got {}",
                    self.min_transition, self.max_transition
                ),
            ));
        }
        if let Some(h) = &self.home {
            if let Some(j) = h.iter().position(|v| !v.is_finite()) {
                return Err(Error::invalid(ctx, format!("execution.home[{j}]"), "expected a finite number"));
            }
        }
        Ok(())
    }
}

/// A check of one pose (q), e.g. the minimum link distance.
pub type PoseCheck<'a> = Box<dyn FnMut(&[f64]) -> CheckResult + 'a>;

/// Relative tolerance of the state check (the periodic part touches its
/// limits by design; rounding must not make it fail).
const TOL: f64 = 1e-9;

/// The check every sample of a lead-in / lead-out passes: joint position,
/// velocity, acceleration and torque limits (nominal parameters, as the
/// design's torque constraints), the design's Cartesian workspace
/// constraints, and the collision hook.
pub struct StateCheck<'a> {
    robot: &'a Robot,
    limits: &'a JointLimitSpec,
    theta: Vec<f64>,
    cart: Vec<(Frame, Shape, String)>,
    torque: bool,
    ws: Workspace,
    tau: Vec<f64>,
    margins: Vec<(f64, nalgebra::Vector3<f64>)>,
    /// Extra check per pose (q): the place for the collision check
    /// (see [`StateCheck::with_pose_check`]).
    pose_check: Option<PoseCheck<'a>>,
}

impl<'a> StateCheck<'a> {
    /// The check of a design problem's limits and workspace.
    pub fn new(p: &'a Problem) -> Result<StateCheck<'a>> {
        let mut cart = Vec::with_capacity(p.design.workspace.len());
        for (i, c) in p.design.workspace.iter().enumerate() {
            let field = format!("workspace[{i}]");
            let frame = c.resolve(&p.robot, &p.design.name, &field)?;
            cart.push((
                frame,
                c.shape.clone(),
                format!("{field} ({}, {})", c.frame.as_deref().unwrap_or("end effector"), c.shape.describe()),
            ));
        }
        let check = StateCheck {
            robot: &p.robot,
            limits: &p.limits,
            theta: p.robot.nominal_params().as_slice().to_vec(),
            cart,
            torque: p.limits.torque.iter().any(|t| t.is_finite()),
            ws: Workspace::new(&p.robot),
            tau: vec![0.0; p.robot.dof()],
            margins: Vec::new(),
            pose_check: None,
        };
        // every pose also keeps the design's minimum distance (self, floor,
        // cell) when the robot has collision geometry
        let mut cws = Workspace::new(&p.robot);
        let constraints = &p.constraints;
        // the poses come along sampled paths: the pairs' last normals carry over
        let mut hints = Vec::new();
        Ok(check.with_pose_check(move |q| match constraints.collision_along(&mut cws, q, &mut hints) {
            None => Ok(()),
            Some(c) => Err(format!(
                "collision {}: distance {:.4} m (penetration depth {:.4} m), below the margin {} m",
                c.pair, c.distance, c.depth, c.margin
            )),
        }))
    }

    /// Adds a check of every pose (e.g. the minimum link distance).
    pub fn with_pose_check(mut self, f: impl FnMut(&[f64]) -> CheckResult + 'a) -> Self {
        self.pose_check = Some(Box::new(f));
        self
    }

    /// `Err(what, where, by how much)` at the first violated limit.
    pub fn check(&mut self, q: &[f64], qd: &[f64], qdd: &[f64]) -> CheckResult {
        let l = self.limits;
        for (j, jt) in self.robot.joints.iter().enumerate() {
            let [lo, hi] = l.position[j];
            let pad = TOL * (1.0 + lo.abs().max(hi.abs()));
            if q[j] < lo - pad || q[j] > hi + pad {
                return Err(format!("joint `{}` position {:.6} outside [{lo:.6}, {hi:.6}]", jt.name, q[j]));
            }
            for (what, v, lim) in [("velocity", qd[j], l.velocity[j]), ("acceleration", qdd[j], l.acceleration[j])] {
                if v.abs() > lim * (1.0 + TOL) {
                    return Err(format!("joint `{}` {what} {v:.6} beyond the limit ±{lim:.6}", jt.name));
                }
            }
        }
        if self.torque {
            inverse_dynamics(self.robot, &mut self.ws, &self.theta, q, qd, qdd, &mut self.tau);
            for (j, jt) in self.robot.joints.iter().enumerate() {
                let lim = l.torque[j];
                if self.tau[j].abs() > lim * (1.0 + TOL) {
                    return Err(format!("joint `{}` torque {:.4} beyond the limit ±{lim:.4}", jt.name, self.tau[j]));
                }
            }
        }
        for (frame, shape, name) in &self.cart {
            let pt = frame_point(self.robot, &mut self.ws, q, frame);
            self.margins.clear();
            shape.margins(&pt, &mut self.margins);
            if let Some(m) = self.margins.iter().map(|m| m.0).min_by(f64::total_cmp) {
                if m < -1e-9 {
                    return Err(format!("{name}: {:.4} m outside at [{:.3}, {:.3}, {:.3}]", -m, pt[0], pt[1], pt[2]));
                }
            }
        }
        if let Some(f) = &mut self.pose_check {
            f(q)?;
        }
        Ok(())
    }
}

/// The delivered trajectory of a design, or why none is playable.
#[derive(Debug, Clone, Serialize)]
pub struct Execution {
    /// The delivered trajectory (None when no lead-in / lead-out fits).
    pub delivered: Option<Delivered>,
    /// Why no delivered trajectory could be built (None when it was).
    pub problem: Option<String>,
    /// Every sample of the delivered trajectory passed the state check on
    /// the `check_rate` grid (lead parts and periods).
    pub verified: bool,
    /// Verification grid (Hz).
    pub check_rate: f64,
    /// Whether the delivered trajectory keeps the robot clear of itself,
    /// the floor and the cell ([`Safety`]).
    pub safety: Safety,
}

/// How collisions were checked on the delivered trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CollisionCheck {
    /// The design's collision constraints (minimum distance `margin`) held
    /// at every sample of the delivered trajectory on the `check_rate` grid.
    Imposed,
    /// `[collision] enabled = false`: the search ignored collisions; the
    /// delivered trajectory was checked afterwards on the `check_rate` grid
    /// against the robot's collision geometry (self, floor, the design's
    /// obstacles and attached shapes), without a margin.
    CheckedAfterwards,
    /// The robot file gives no collision geometry and the design no
    /// obstacle: nothing could be checked.
    NotChecked,
}

/// The least distance found on the delivered trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Closest {
    /// `self: a – b` or `world: a – floor`.
    pub pair: String,
    /// Signed distance (m; negative: penetration), capped at `cap`.
    pub distance: f64,
    /// Distances above this were not resolved (m).
    pub cap: f64,
    /// Time in the delivered trajectory (s).
    pub t: f64,
    /// Segment of that time ([`crate::trajectory::lead::LEAD_IN`], period
    /// 1..N, [`crate::trajectory::lead::LEAD_OUT`]).
    pub segment: i64,
    /// Samples in contact or collision (least distance ≤ 0).
    pub colliding_samples: usize,
    /// Samples checked.
    pub samples: usize,
}

/// Whether the delivered trajectory may be played: the verdict a user
/// reads before running it on the robot.
///
/// Collision distances are between the convex hulls of the collision
/// meshes grown by the robot file's `collision_padding` (and the design's
/// primitives): lower bounds of the distances between the vendor's meshes.
/// A design whose search ignored collisions (`[collision] enabled = false`,
/// e.g. a benchmark against a reference without collision checks) is
/// still checked here, and called unsafe when any pair touches.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Safety {
    /// How collisions were checked.
    pub collisions: CollisionCheck,
    /// `Some(true)`: every sample is within the limits and collision-free
    /// (for `Imposed`: at least the margin apart); `Some(false)`: not;
    /// `None`: collisions could not be checked.
    pub safe: Option<bool>,
    /// The least distance over the delivered trajectory
    /// (`CheckedAfterwards` only; for `Imposed` the report's per-pair
    /// margins hold the least distances over the period).
    pub closest: Option<Closest>,
    /// One sentence: the verdict and why.
    pub statement: String,
}

impl Safety {
    fn none(why: &str) -> Safety {
        Safety {
            collisions: CollisionCheck::NotChecked,
            safe: Some(false),
            closest: None,
            statement: format!("NOT safe to play: {why}"),
        }
    }
}

/// Distances above this are not resolved in the after-the-fact check (m).
pub const SAFETY_CAP: f64 = 0.1;

/// The safety verdict of a delivered trajectory `d`; `verified`: why it
/// failed the check of the design's limits (None: it passed).
fn safety(p: &Problem, d: &Delivered, verified: Option<&str>, rate: f64) -> Result<Safety> {
    if let Some(e) = verified {
        return Ok(Safety {
            collisions: if p.constraints.scene().is_some() {
                CollisionCheck::Imposed
            } else {
                CollisionCheck::NotChecked
            },
            safe: Some(false),
            closest: None,
            statement: format!("NOT safe to play: {e}"),
        });
    }
    if let Some(sc) = p.constraints.scene() {
        return Ok(Safety {
            collisions: CollisionCheck::Imposed,
            safe: Some(true),
            closest: None,
            statement: format!(
                "safe to play by idexp's check: every sample on the {rate} Hz grid within the limits, and every checked pair at least {} m apart",
                sc.margin
            ),
        });
    }
    if let Some(why) = &p.robot.geometry_error {
        // only reached with [collision] enabled = false: a design that checks refuses such a robot
        return Ok(Safety {
            collisions: CollisionCheck::NotChecked,
            safe: None,
            closest: None,
            statement: format!("collisions NOT checked: [collision] is off and the robot's {why}; every sample on the {rate} Hz grid is within the limits"),
        });
    }
    let spec = crate::robot::collision::CollisionSpec {
        enabled: true,
        margin: 0.0,
        requested: false,
        ..p.design.collision.clone()
    };
    let scene = crate::robot::collision::CollisionScene::new(&p.robot, &spec, std::path::Path::new(""), &p.design.name)?;
    let Some(sc) = scene.filter(|s| !s.is_empty()) else {
        return Ok(Safety {
            collisions: CollisionCheck::NotChecked,
            safe: None,
            closest: None,
            statement: format!(
                "collisions NOT checked: the robot file gives no collision geometry{}; every sample on the {rate} Hz grid is within the limits",
                if p.design.collision.enabled { "" } else { " and [collision] is off" }
            ),
        });
    };
    let closest = closest_on(p, &sc, d, rate);
    let safe = closest.as_ref().is_none_or(|c| c.distance > 0.0);
    let statement = match (&closest, safe) {
        (Some(c), false) => format!(
            "NOT safe to play: the design imposes no collision constraint ([collision] enabled = false), and the delivered \
             trajectory is in collision at {} of its {} samples ({rate} Hz); deepest: `{}` at t = {:.3} s ({}), distance {:.4} m",
            c.colliding_samples,
            c.samples,
            c.pair,
            c.t,
            segment_name(c.segment),
            c.distance
        ),
        (Some(c), true) => format!(
            "collision-free by idexp's check although the design imposes no collision constraint ([collision] enabled = false): \
             least distance {} m (`{}` at t = {:.3} s, {}); no margin was kept",
            if c.distance >= c.cap {
                format!("≥ {}", c.cap)
            } else {
                format!("{:.4}", c.distance)
            },
            c.pair,
            c.t,
            segment_name(c.segment)
        ),
        (None, _) => "collision-free by idexp's check (no checked pair)".to_string(),
    };
    Ok(Safety {
        collisions: CollisionCheck::CheckedAfterwards,
        safe: Some(safe),
        closest,
        statement,
    })
}

/// `lead-in`, `period 2`, `lead-out`.
pub fn segment_name(seg: i64) -> String {
    match seg {
        lead::LEAD_IN => "lead-in".to_string(),
        lead::LEAD_OUT => "lead-out".to_string(),
        k => format!("period {k}"),
    }
}

/// The least capped distance of `sc` over every sample of `d` at `rate`
/// Hz (the first sample of least distance on ties). Samples are checked in
/// chunks in parallel; the reduction is in time order, so the result does
/// not depend on the thread count.
fn closest_on(p: &Problem, sc: &crate::robot::collision::CollisionScene, d: &Delivered, rate: f64) -> Option<Closest> {
    use rayon::prelude::*;
    let n = d.home.len();
    let m = (d.duration() * rate - 1e-6).ceil().max(0.0) as usize;
    let plan = d.rows(rate);
    const CHUNK: usize = 512;
    let chunks: Vec<usize> = (0..=m).step_by(CHUNK).collect();
    let best = chunks
        .par_iter()
        .map(|&k0| {
            let mut kin = crate::robot::kinematics::Kin::new(p.robot.dof());
            let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            let mut best: Option<(usize, i64, crate::robot::collision::PairDistance)> = None;
            let mut colliding = 0;
            for k in k0..(k0 + CHUNK).min(m + 1) {
                // a sample repeated bitwise in later periods counts once per
                // repetition; the first of least distance is never a repetition
                let times = plan.multiplicity(d, k);
                if times == 0 {
                    continue;
                }
                let seg = d.eval(k as f64 / rate, &mut q, &mut qd, &mut qdd);
                if let Some(w) = sc.worst_at(&p.robot, &mut kin, &q, SAFETY_CAP) {
                    colliding += times * usize::from(w.distance <= 0.0);
                    if best.as_ref().is_none_or(|b| w.distance < b.2.distance) {
                        best = Some((k, seg, w));
                    }
                }
            }
            (best, colliding)
        })
        .collect::<Vec<_>>();
    let colliding_samples = best.iter().map(|b| b.1).sum();
    let (k, segment, w) = best
        .into_iter()
        .filter_map(|b| b.0)
        .reduce(|a, b| if b.2.distance < a.2.distance { b } else { a })?;
    Some(Closest {
        pair: w.label,
        distance: w.distance,
        cap: SAFETY_CAP,
        t: k as f64 / rate,
        segment,
        colliding_samples,
        samples: m + 1,
    })
}

/// The home pose of a design: `execution.home`, else the motion's rest
/// pose ([`Motion::rest_pose`]: a Fourier series' q0, a rest-to-rest
/// motion's start).
pub fn home_of(p: &Problem, tr: &ShapeMotion) -> Vec<f64> {
    if let Some(h) = &p.design.execution.home {
        return h.clone();
    }
    match &p.shape {
        // free or given ends: the start is the design's, home stays q0
        crate::trajectory::Shape::BSpline(l) if l.leaves_home() => l.q0.clone(),
        _ => tr.rest_pose(),
    }
}

/// Builds the delivered trajectory of `tr` for design `p`: home → lead-in →
/// `periods` periods → lead-out → home, every lead sample checked with
/// [`StateCheck`] on the `check_rate` grid, then the whole delivered
/// trajectory verified on that grid.
pub fn deliver(p: &Problem, tr: &ShapeMotion) -> Result<Execution> {
    let e = &p.design.execution;
    let rate = p.design.limits.check_rate;
    let dt = 1.0 / rate;
    let mut check = StateCheck::new(p)?;
    if !e.rest_to_rest {
        let d = Delivered {
            home: tr.rest_pose(),
            lead_in: None,
            periodic: tr.clone(),
            periods: e.periods,
            lead_out: None,
        };
        let verified = verify(p, &d, rate)?;
        let safety = safety(p, &d, verified.as_ref().err().map(|s| s.as_str()), rate)?;
        return Ok(Execution {
            verified: verified.is_ok(),
            delivered: Some(d),
            problem: None,
            check_rate: rate,
            safety,
        });
    }
    let home = home_of(p, tr);
    let rest = State::rest(&home);
    let start = State::of(tr, 0.0);
    let at_home = |s: &State| s.q.iter().zip(&home).all(|(a, b)| (a - b).abs() <= 1e-12) && s.qd.iter().chain(&s.qdd).all(|v| v.abs() <= 1e-12);
    let (lead_in, lead_out) = if tr.ends() == crate::trajectory::Ends::RestToRest {
        // a rest-to-rest motion: a lead where its start (end) is not home
        let own_end = matches!(&p.shape, crate::trajectory::Shape::BSpline(l) if !l.ends_at_start());
        // the end of a motion that ends where it starts is its start (as before free ends)
        let end = if own_end { State::of(tr, tr.duration()) } else { start.clone() };
        let mut lead = |a: &State, b: &State, what: &str| -> std::result::Result<Option<lead::Quintic>, String> {
            if (what == "lead-in" && at_home(b)) || (what == "lead-out" && at_home(a)) {
                return Ok(None);
            }
            lead::shortest(a, b, e.min_transition, e.max_transition, dt, |_, q, qd, qdd| check.check(q, qd, qdd))
                .map(Some)
                .map_err(|err| format!("{what} {} the home pose: {err}", if what == "lead-in" { "from" } else { "to" }))
        };
        let lead_in = match lead(&rest, &start, "lead-in") {
            Ok(l) => l,
            Err(msg) => return Ok(failed(msg, rate)),
        };
        let lead_out = match lead(&end, &rest, "lead-out") {
            Ok(l) => l,
            Err(msg) => return Ok(failed(msg, rate)),
        };
        (lead_in, lead_out)
    } else if at_home(&start) {
        (None, None)
    } else {
        let lead_in = lead::shortest(&rest, &start, e.min_transition, e.max_transition, dt, |_, q, qd, qdd| check.check(q, qd, qdd));
        let lead_in = match lead_in {
            Ok(l) => l,
            Err(err) => return Ok(failed(format!("lead-in from the home pose: {err}"), rate)),
        };
        // the state at the end of every period is the state at t = 0
        let lead_out = lead::shortest(&start, &rest, e.min_transition, e.max_transition, dt, |_, q, qd, qdd| check.check(q, qd, qdd));
        let lead_out = match lead_out {
            Ok(l) => l,
            Err(err) => return Ok(failed(format!("lead-out to the home pose: {err}"), rate)),
        };
        (Some(lead_in), Some(lead_out))
    };
    let d = Delivered {
        home,
        lead_in,
        periodic: tr.clone(),
        periods: e.periods,
        lead_out,
    };
    let verified = verify(p, &d, rate)?;
    let safety = safety(p, &d, verified.as_ref().err().map(|s| s.as_str()), rate)?;
    Ok(Execution {
        verified: verified.is_ok(),
        problem: verified.err(),
        delivered: Some(d),
        check_rate: rate,
        safety,
    })
}

fn failed(problem: String, rate: f64) -> Execution {
    Execution {
        delivered: None,
        problem: Some(problem),
        verified: false,
        check_rate: rate,
        safety: Safety::none("no delivered trajectory is playable rest to rest"),
    }
}

/// Checks every sample of the delivered trajectory at `rate` Hz: the first
/// violation in time (`Err` its sentence). A sample that repeats an earlier
/// one bitwise ([`lead::RowPlan`]: periods 2 and later) passes or fails with
/// it, so only the samples it repeats are checked. Samples are checked in chunks in
/// parallel, each with its own check from [`StateCheck::new`]; the first
/// failing chunk in time gives the answer, so it does not depend on the
/// thread count.
fn verify(p: &Problem, d: &Delivered, rate: f64) -> Result<std::result::Result<(), String>> {
    use rayon::prelude::*;
    let n = d.home.len();
    let m = (d.duration() * rate - 1e-6).ceil().max(0.0) as usize;
    let plan = d.rows(rate);
    const CHUNK: usize = 1024;
    let chunks: Vec<usize> = (0..=m).step_by(CHUNK).collect();
    let results = chunks
        .par_iter()
        .map(|&k0| -> Result<std::result::Result<(), String>> {
            let mut check = StateCheck::new(p)?;
            let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            for k in k0..(k0 + CHUNK).min(m + 1) {
                if plan.row(d, k).1 != k {
                    continue;
                }
                let t = k as f64 / rate;
                let seg = d.eval(t, &mut q, &mut qd, &mut qdd);
                if let Err(e) = check.check(&q, &qd, &qdd) {
                    return Ok(Err(format!("delivered trajectory at t = {t:.3} s (segment {seg}): {e}")));
                }
            }
            Ok(Ok(()))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(results.into_iter().find(|r| r.is_err()).unwrap_or(Ok(())))
}
