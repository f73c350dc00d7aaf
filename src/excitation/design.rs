//! The excitation design file (TOML): robot, trajectory parameterisation,
//! criterion, limits, workspace constraints, solver settings.
//!
//! ```toml
//! name = "ur5_full"                 # output folder name (default: the file stem)
//! robot = "robots/ur5.toml"         # relative to this file
//! seed = 1
//! time_limit = 60.0                 # optional wall-clock budget (s); results then depend on the machine
//! max_evaluations = 200000          # optional budget of criterion evaluations (GA + refinements): the same
//!                                   # result on any machine and load (with a GA of fixed length)
//!
//! [trajectory]
//! harmonics = 5                     # n_h
//! frequency = 0.1                   # base frequency f = ω/2π (Hz)
//! q0 = [0, 0, 0, 0, 0, 0]           # offsets (default: the middle of each joint range, 0 for unbounded joints)
//! vary_q0 = false                   # q0 a design variable too
//! at_rest = false                   # start and end at rest (q̇ = q̈ = 0 at t = 0)
//! controller_rate = 1000.0          # rate of trajectory.csv (Hz)
//! shape = "fourier"                 # fourier (periodic, the default) | bspline (rest to rest)
//! # with shape = "bspline" (harmonics, vary_q0 and at_rest do not apply):
//! degree = 5                        # 3, 4 or 5
//! segments = 11                     # equal knot intervals (≥ 7 − degree); (segments + degree − 6) free control points per joint
//! duration = 10.0                   # length of the motion (s); default 1/frequency
//! start = "q0"                      # q0 | free | [q1, ..., qn]: at rest at q0, at a pose the search
//!                                   # chooses (within the position limits), or at this given pose
//! end = "start"                     # start | free | [q1, ..., qn]: at rest where it started, at a pose of
//!                                   # its own (free or given; needs execution.periods = 1)
//! waypoints = 7                     # optional: at rest at this many waypoints T/(waypoints − 1) apart,
//!                                   # the interior ones free (segments: a multiple of waypoints − 1, default waypoints − 1)
//!
//! [objective]
//! criterion = "cond"                # cond | log_det | inv_sigma_min
//! scaling = "unit_column"           # unit_column | nominal | none
//! columns = "base"                  # base (with drive/friction) | inertial | payload | gains
//! sample_rate = 10.0                # regressor samples per second over one period
//! noise = [1.0, ...]                # torque noise std per joint (N·m): weights W and predicted std devs
//!
//! [limits]
//! position = 0.8                    # usable fraction of each joint's half range, about its centre
//! velocity = 1.0                    # fraction of the velocity limit (0: not imposed)
//! acceleration = 1.0                # fraction of the acceleration limit (0: not imposed)
//! torque = 0.0                      # fraction of the effort limit (0: not imposed)
//! grid_rate = 50.0                  # grid of torque and Cartesian constraints (Hz)
//! check_rate = 1000.0               # verification grid of the report (Hz)
//! missing = "error"                 # a limit asked for but missing in the robot: error | skip
//!
//! [execution]                       # how the trajectory is played (see excitation::execution)
//! rest_to_rest = true               # lead-in from home at rest, periods, lead-out to home at rest
//! home = [0, 0, 0, 0, 0, 0]         # default: q0
//! periods = 3                       # periodic part repeated for averaging
//!
//! [[workspace]]                     # Cartesian constraints, any number
//! frame = "tool0"                   # default: the end effector
//! shape = { type = "half_space", normal = [0, 0, 1], offset = 0.05 }
//!
//! [collision]                     # checked when the robot has collision geometry
//! enabled = true
//! margin = 0.02                     # minimum distance (m) for every checked pair
//! band = 0.1                        # distances above margin + band count as margin + band (m)
//! self = true                       # link-to-link pairs (not adjacent, not allowed by the robot file)
//! floor = true                      # every link but the base above z = 0 of the base frame
//!
//! [[collision.obstacle]]            # cell obstacles, base frame
//! name = "fence"
//! shape = { type = "box", size = [2.0, 0.05, 1.5] }   # box | cylinder | sphere | capsule | plane | mesh
//! xyz = [0.0, -0.8, 0.75]
//! rpy = [0.0, 0.0, 0.0]
//!
//! [[collision.attached]]            # tool or payload fixed to a robot frame
//! name = "gripper"
//! frame = "tool0"
//! shape = { type = "cylinder", radius = 0.04, length = 0.12 }
//! xyz = [0.0, 0.0, 0.06]
//!
//! [payload]                        # a payload on the flange (objective.columns = "payload": its 10 parameters only)
//! frame = "tool0"                   # default: the end effector
//! mass = 2.0                        # nominal (kg), com (m) and inertia about the com, [Ixx, Ixy, Ixz, Iyy, Iyz, Izz] (kg·m²)
//! com = [0.0, 0.0, 0.05]
//!
//! [ga]
//! population = 40
//! generations = 30
//! elite = 2
//! crossover = 0.9                   # SBX probability
//! eta_crossover = 10.0
//! mutation = 0.05                   # per-gene probability (default 1/n_vars when 0)
//! eta_mutation = 20.0
//!
//! [refine]
//! algorithm = "slsqp"               # slsqp | mma | none
//! starts = 2                        # best distinct GA individuals refined
//! max_evals = 300                   # per start
//! xtol_rel = 1e-7
//! smooth = 0.0                      # cond: > 0 adds a first stage on a smooth surrogate with this exponent
//! bundle = 0                        # cond, inv_sigma_min: > 0 refines the epigraph form over this many eigenvalues at each end
//! bundle_weight = 0.1               # weight of the epigraph objective (length of SLSQP's first steps)
//! parallel = 1                      # starts refined at the same time (results per start unchanged)
//! restarts = 0                      # then restarts from the best refined point perturbed by ...
//! perturb = 0.05                    # ... this fraction of each variable's half range (uniform)
//! stall = 0                         # > 0: after this many rounds of restarts without a better point,
//!                                   # the restarts move on to the next two GA individuals, refined (0: never)
//! elites = 1                        # > 1: the rounds of restarts perturb the best `elites` distinct
//!                                   # refined points in turn (1: always the best point so far)
//! polish = 0                        # > 0: after each SLSQP stage, MMA for at most this many evaluations
//!                                   # from SLSQP's last iterate (feasible iterates; the better point is kept)
//! patience = 0                      # > 0: a stage ends once its best feasible criterion has not fallen by
//!                                   # 1e-4 (relative) in this many evaluations (0: only max_evals ends it)
//! perturb_joints = 0                # > 0: a restart moves the coefficients of this many joints only,
//!                                   # drawn by the restart's seed (0: every variable)
//! perturb_adapt = 1.0               # > 1: each perturbed point's own size, times this after a round from it
//!                                   # found a better point, divided by it otherwise (1: always `perturb`)
//! repair = false                   # true: repair and try the best near-feasible iterate SLSQP met
//! ```

use super::objective::{Columns, Criterion, Scaling};
use crate::error::{Error, Result};
use crate::robot::cartesian::CartesianConstraint;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A complete excitation design.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExciteDesign {
    /// Design name (output folder); default: the file stem.
    #[serde(default)]
    pub name: String,
    /// Robot file, relative to the design file.
    pub robot: PathBuf,
    /// Seed of every random choice.
    #[serde(default = "one")]
    pub seed: u64,
    /// Optional wall-clock budget in seconds for the whole search (GA + refinement).
    #[serde(default)]
    pub time_limit: Option<f64>,
    /// Optional budget of criterion evaluations for the whole search (the
    /// GA's individuals and every refinement's evaluations): the search stops
    /// where it is when it is spent, whatever the machine's speed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_evaluations: Option<u64>,
    /// Trajectory parameterisation.
    #[serde(default)]
    pub trajectory: TrajectorySpec,
    /// Criterion.
    #[serde(default)]
    pub objective: ObjectiveSpec,
    /// Joint limits used.
    #[serde(default)]
    pub limits: LimitsSpec,
    /// Cartesian workspace constraints.
    #[serde(default)]
    pub workspace: Vec<CartesianConstraint>,
    /// Collision checking (minimum distance per checked pair).
    #[serde(default)]
    pub collision: crate::robot::collision::CollisionSpec,
    /// Genetic algorithm.
    #[serde(default)]
    pub ga: GaSpec,
    /// Gradient refinement.
    #[serde(default)]
    pub refine: RefineSpec,
    /// How the trajectory is delivered: rest-to-rest from a home pose, periods.
    #[serde(default)]
    pub execution: super::execution::ExecutionSpec,
    /// A payload the robot carries during the experiment (its nominal mass,
    /// centre of mass and inertia, for the torques; its geometry goes in
    /// `[[collision.attached]]`); with `objective.columns = "payload"` the
    /// design excites the payload's parameters only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<crate::robot::payload::PayloadSpec>,
}

fn one() -> u64 {
    1
}

/// `[trajectory]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrajectorySpec {
    /// Number of harmonics n_h (default 5, paper 000).
    pub harmonics: usize,
    /// Base frequency in Hz (default 0.1, paper 000 / 002).
    pub frequency: f64,
    /// Offsets q0 (default: middle of each joint range).
    pub q0: Option<Vec<f64>>,
    /// q0 is a design variable.
    pub vary_q0: bool,
    /// Start and end at rest.
    pub at_rest: bool,
    /// Rate of trajectory.csv (Hz).
    pub controller_rate: f64,
    /// The trajectory shape (default the Fourier series).
    #[serde(skip_serializing_if = "ShapeKind::is_fourier")]
    pub shape: ShapeKind,
    /// B-spline degree (3 … 5; default [`DEFAULT_DEGREE`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub degree: Option<usize>,
    /// B-spline segments (default [`DEFAULT_SEGMENTS`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segments: Option<usize>,
    /// B-spline duration (s; default one period 1/frequency).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub duration: Option<f64>,
    /// B-spline start pose: q0 (default), a design variable, or a given pose.
    #[serde(skip_serializing_if = "StartPose::is_q0")]
    pub start: StartPose,
    /// B-spline end pose: the start pose (default), a design variable of its own, or a given pose.
    #[serde(skip_serializing_if = "EndPose::is_start")]
    pub end: EndPose,
    /// B-spline waypoints at rest, T/(waypoints − 1) apart (default: only the start and the end).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub waypoints: Option<usize>,
}

/// `start`/`end` in a file: a word or a pose.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(untagged)]
enum PoseWord {
    Word(String),
    Pose(Vec<f64>),
}

/// `[trajectory] start`: where a B-spline starts (at rest).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(try_from = "PoseWord", into = "PoseWord")]
pub enum StartPose {
    /// At q0, the home pose (default).
    #[default]
    Q0,
    /// Anywhere within the position limits: a design variable per joint,
    /// reached from home by a lead-in.
    Free,
    /// At this pose (one value per joint, within the position limits),
    /// reached from home by a lead-in.
    Pose(Vec<f64>),
}

impl StartPose {
    fn is_q0(&self) -> bool {
        *self == StartPose::Q0
    }

    /// The given pose, if any.
    pub fn given(&self) -> Option<&Vec<f64>> {
        match self {
            StartPose::Pose(q) => Some(q),
            _ => None,
        }
    }
}

impl TryFrom<PoseWord> for StartPose {
    type Error = String;
    fn try_from(w: PoseWord) -> std::result::Result<Self, String> {
        match w {
            PoseWord::Word(s) if s == "q0" => Ok(StartPose::Q0),
            PoseWord::Word(s) if s == "free" => Ok(StartPose::Free),
            PoseWord::Word(s) => Err(format!("unknown start `{s}`: expected `q0` or `free` or a pose [q1, ..., qn]")),
            PoseWord::Pose(q) => Ok(StartPose::Pose(q)),
        }
    }
}

impl From<StartPose> for PoseWord {
    fn from(p: StartPose) -> Self {
        match p {
            StartPose::Q0 => PoseWord::Word("q0".into()),
            StartPose::Free => PoseWord::Word("free".into()),
            StartPose::Pose(q) => PoseWord::Pose(q),
        }
    }
}

/// `[trajectory] end`: where a B-spline ends (at rest).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(try_from = "PoseWord", into = "PoseWord")]
pub enum EndPose {
    /// Where it started (default).
    #[default]
    Start,
    /// Anywhere within the position limits: a design variable per joint,
    /// left to home by a lead-out.
    Free,
    /// At this pose (one value per joint, within the position limits),
    /// left to home by a lead-out.
    Pose(Vec<f64>),
}

impl EndPose {
    fn is_start(&self) -> bool {
        *self == EndPose::Start
    }

    /// The given pose, if any.
    pub fn given(&self) -> Option<&Vec<f64>> {
        match self {
            EndPose::Pose(q) => Some(q),
            _ => None,
        }
    }
}

impl TryFrom<PoseWord> for EndPose {
    type Error = String;
    fn try_from(w: PoseWord) -> std::result::Result<Self, String> {
        match w {
            PoseWord::Word(s) if s == "start" => Ok(EndPose::Start),
            PoseWord::Word(s) if s == "free" => Ok(EndPose::Free),
            PoseWord::Word(s) => Err(format!("unknown end `{s}`: expected `start` or `free` or a pose [q1, ..., qn]")),
            PoseWord::Pose(q) => Ok(EndPose::Pose(q)),
        }
    }
}

impl From<EndPose> for PoseWord {
    fn from(p: EndPose) -> Self {
        match p {
            EndPose::Start => PoseWord::Word("start".into()),
            EndPose::Free => PoseWord::Word("free".into()),
            EndPose::Pose(q) => PoseWord::Pose(q),
        }
    }
}

/// `[trajectory] shape`: which [`crate::trajectory::Shape`] the design uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ShapeKind {
    /// Periodic finite Fourier series (default).
    #[default]
    Fourier,
    /// Clamped uniform B-spline at rest at both ends ([`crate::trajectory::bspline`]).
    Bspline,
}

impl ShapeKind {
    fn is_fourier(&self) -> bool {
        *self == ShapeKind::Fourier
    }
}

/// Default B-spline degree (quintic).
pub const DEFAULT_DEGREE: usize = 5;
/// Default number of B-spline segments: with degree 5, ten free control
/// points per joint, as many design variables as the default five harmonics.
pub const DEFAULT_SEGMENTS: usize = 11;

impl TrajectorySpec {
    /// The duration of the motion (s): one period 1/frequency, or a B-spline's `duration`.
    pub fn motion_duration(&self) -> f64 {
        match self.shape {
            ShapeKind::Fourier => 1.0 / self.frequency,
            ShapeKind::Bspline => self.duration.unwrap_or(1.0 / self.frequency),
        }
    }

    /// The shape of this design for the start (and end) pose, or centre, `q0`
    /// (errors name the field).
    pub fn shape(&self, q0: Vec<f64>) -> Result<crate::trajectory::Shape> {
        Ok(match self.shape {
            ShapeKind::Fourier => {
                crate::trajectory::FourierLayout::new(q0, self.harmonics, std::f64::consts::TAU * self.frequency, self.vary_q0, self.at_rest)?.into()
            }
            ShapeKind::Bspline => {
                crate::trajectory::bspline::BSplineLayout::new(q0, self.degree.unwrap_or(DEFAULT_DEGREE), self.bspline_segments(), self.motion_duration())?
                    .with_free_ends(self.start == StartPose::Free, self.end == EndPose::Free)
                    .with_given_ends(self.start.given().cloned(), self.end.given().cloned())?
                    .with_waypoints(self.waypoints.unwrap_or(2))?
                    .into()
            }
        })
    }

    /// B-spline segments: `segments`, else [`DEFAULT_SEGMENTS`], or one per
    /// piece between `waypoints`.
    pub fn bspline_segments(&self) -> usize {
        match (self.segments, self.waypoints) {
            (Some(s), _) => s,
            (None, Some(w)) if w > 2 => w - 1,
            _ => DEFAULT_SEGMENTS,
        }
    }

    /// Whether a B-spline's end can differ from its start (a free or given
    /// end pose other than the start's): it cannot be repeated back to back.
    pub fn ends_elsewhere(&self) -> bool {
        match &self.end {
            EndPose::Start => false,
            EndPose::Free => true,
            EndPose::Pose(e) => self.start.given() != Some(e),
        }
    }

    /// Checks the given start and end poses against the joint count and the
    /// position limits `position` (per joint, the design's ranges): the
    /// convex hull of the control points then keeps the motion within them.
    pub fn check_poses(&self, position: &[[f64; 2]], ctx: &str) -> Result<()> {
        for (field, pose) in [("trajectory.start", self.start.given()), ("trajectory.end", self.end.given())] {
            let Some(q) = pose else { continue };
            if q.len() != position.len() {
                return Err(Error::invalid(
                    ctx,
                    field,
                    format!("expected a pose of {} joint values, got {}", position.len(), q.len()),
                ));
            }
            for (j, (&v, &[lo, hi])) in q.iter().zip(position).enumerate() {
                if !(v.is_finite() && v >= lo && v <= hi) {
                    return Err(Error::invalid(
                        ctx,
                        format!("{field}[{j}]"),
                        format!(
                            "{v} is outside the design's position range [{lo}, {hi}] of joint {} (limits.position, limits.position_range)",
                            j + 1
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The checks of the shape's fields (`ctx` names the file).
    fn validate_shape(&self, ctx: &str) -> Result<()> {
        let bad = |field: &str, msg: String| Err(Error::invalid(ctx, field, msg));
        match self.shape {
            ShapeKind::Fourier => {
                for (f, given) in [
                    ("trajectory.degree", self.degree.is_some()),
                    ("trajectory.segments", self.segments.is_some()),
                    ("trajectory.duration", self.duration.is_some()),
                    ("trajectory.start", self.start != StartPose::Q0),
                    ("trajectory.end", self.end != EndPose::Start),
                    ("trajectory.waypoints", self.waypoints.is_some()),
                ] {
                    if given {
                        return bad(
                            f,
                            "applies to shape = \"bspline\" only (the Fourier series: harmonics and frequency); remove it or set shape = \"bspline\"".into(),
                        );
                    }
                }
            }
            ShapeKind::Bspline => {
                let p = self.degree.unwrap_or(DEFAULT_DEGREE);
                if !(3..=crate::trajectory::bspline::MAX_DEGREE).contains(&p) {
                    return bad("trajectory.degree", format!("expected a B-spline degree of 3, 4 or 5, got {p}"));
                }
                let s = self.bspline_segments();
                if let Some(w) = self.waypoints {
                    let pieces = w.max(2) - 1;
                    if !(2..=1000).contains(&w) {
                        return bad(
                            "trajectory.waypoints",
                            format!("expected 2..=1000 waypoints (the start and the end count), got {w}"),
                        );
                    }
                    if s % pieces != 0 || (pieces > 1 && s / pieces + p < 6) || s > 1000 {
                        return bad(
                            "trajectory.segments",
                            format!(
                                "expected a multiple of the {pieces} pieces between {w} waypoints, at least {} per piece for degree {p} (three control points are fixed at each waypoint), at most 1000, got {s}",
                                6usize.saturating_sub(p).max(1)
                            ),
                        );
                    }
                }
                if s + p < 7 || s > 1000 {
                    return bad(
                        "trajectory.segments",
                        format!(
                            "expected {}..=1000 segments for degree {p} (three control points are fixed at each end), got {s}",
                            7 - p.min(6)
                        ),
                    );
                }
                if let Some(d) = self.duration {
                    if !(d.is_finite() && d > 0.0 && d <= 1e5) {
                        return bad("trajectory.duration", format!("expected a duration in (0, 100000] s, got {d}"));
                    }
                }
                if self.vary_q0 || self.at_rest {
                    return bad(
                        if self.vary_q0 { "trajectory.vary_q0" } else { "trajectory.at_rest" },
                        "applies to shape = \"fourier\" only (a B-spline starts and ends at rest at q0); remove it".into(),
                    );
                }
            }
        }
        Ok(())
    }
}

impl Default for TrajectorySpec {
    fn default() -> Self {
        TrajectorySpec {
            harmonics: 5,
            frequency: 0.1,
            q0: None,
            vary_q0: false,
            at_rest: false,
            controller_rate: 1000.0,
            shape: ShapeKind::Fourier,
            degree: None,
            segments: None,
            duration: None,
            start: StartPose::Q0,
            end: EndPose::Start,
            waypoints: None,
        }
    }
}

/// `[objective]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectiveSpec {
    /// Criterion (default cond).
    pub criterion: Criterion,
    /// Column scaling (default unit columns).
    pub scaling: Scaling,
    /// Columns of C (default: base parameters with drive columns).
    pub columns: Columns,
    /// Regressor samples per second (default 10 Hz).
    pub sample_rate: f64,
    /// Torque noise std per joint (N·m); default 1 for every joint.
    pub noise: Option<Vec<f64>>,
    /// Fix the base columns by name (`["ZZ1", "XX2", ...]`) instead of idexp's choice.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub base_columns: Option<Vec<String>>,
}

impl Default for ObjectiveSpec {
    fn default() -> Self {
        ObjectiveSpec {
            criterion: Criterion::Cond,
            scaling: Scaling::UnitColumn,
            columns: Columns::Base,
            sample_rate: 10.0,
            noise: None,
            base_columns: None,
        }
    }
}

/// `[limits]`: fractions of the robot's limits that the trajectory may use.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LimitsSpec {
    /// Fraction of each joint's half range, about the centre of the range (0 < f ≤ 1).
    pub position: f64,
    /// Fraction of the velocity limit (0: not imposed).
    pub velocity: f64,
    /// Fraction of the acceleration limit (0: not imposed).
    pub acceleration: f64,
    /// Fraction of the effort limit (0: not imposed).
    pub torque: f64,
    /// Constraint grid for torque and Cartesian constraints (Hz).
    pub grid_rate: f64,
    /// Verification grid (Hz).
    pub check_rate: f64,
    /// Per-joint position ranges overriding the robot's ([lower, upper] each; rad or m).
    pub position_range: Option<Vec<[f64; 2]>>,
    /// What to do when a limit class asked for is missing in the robot for
    /// some joint (default: an error naming the joint and the key to set).
    pub missing: MissingLimits,
}

/// `limits.missing`: a limit class the design asks for but the robot lacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MissingLimits {
    /// An error naming the joint and the key to set (default).
    #[default]
    Error,
    /// Leave the missing limits out (listed as "not imposed" in the report).
    Skip,
}

impl Default for LimitsSpec {
    fn default() -> Self {
        LimitsSpec {
            position: 0.8,
            velocity: 1.0,
            acceleration: 1.0,
            torque: 0.0,
            grid_rate: 50.0,
            check_rate: 1000.0,
            position_range: None,
            missing: MissingLimits::Error,
        }
    }
}

/// `[ga]`: real-coded genetic algorithm (one struct with the solver: [`crate::optim::ga::GaSpec`]).
pub use crate::optim::ga::GaSpec;

/// Gradient refinement algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RefineAlgorithm {
    /// nlopt SLSQP (sequential quadratic programming).
    Slsqp,
    /// nlopt MMA (method of moving asymptotes).
    Mma,
    /// No refinement: the GA's best.
    None,
}

/// `[refine]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RefineSpec {
    /// Algorithm.
    pub algorithm: RefineAlgorithm,
    /// Number of best distinct GA individuals refined.
    pub starts: usize,
    /// Evaluation budget per start.
    pub max_evals: u32,
    /// Relative x tolerance.
    pub xtol_rel: f64,
    /// Relative objective tolerance.
    pub ftol_rel: f64,
    /// Exponent p of the smooth first stage for `criterion = "cond"` (0: off).
    pub smooth: f64,
    /// cond or inv_sigma_min: > 0 refines the epigraph form over this many
    /// eigenvalues at each end of the spectrum (0: the criterion itself).
    pub bundle: usize,
    /// Weight w of the epigraph objective w·(u − l): with SLSQP's initial
    /// identity Hessian it sets the length of the first steps (smaller: shorter).
    pub bundle_weight: f64,
    /// Starts refined at the same time (each start's result does not depend on it).
    pub parallel: usize,
    /// Restarts from perturbed copies of the best refined point, after the GA starts.
    pub restarts: usize,
    /// Size of a restart's perturbation, a fraction of each variable's half range.
    pub perturb: f64,
    /// Rounds of restarts without a better point after which the restarts
    /// leave their basin: the next two distinct GA individuals not yet
    /// refined are refined and the better becomes the point the restarts
    /// perturb (0: never; the restarts always perturb the best point so far).
    pub stall: usize,
    /// Evaluation budget of an MMA stage after each SLSQP stage, from
    /// SLSQP's last iterate (0: none). SLSQP crosses infeasible regions and
    /// can end its budget there; MMA's conservative steps come back to
    /// feasible points near where SLSQP went.
    #[serde(skip_serializing_if = "is_zero")]
    pub polish: u32,
    /// How many of the best distinct refined points the rounds of restarts
    /// perturb, in turn (round r from the (r mod k)-th best so far; 1: the
    /// best point so far, as before this field).
    #[serde(skip_serializing_if = "is_one")]
    pub elites: usize,
    /// A stage of a refinement ends once its best feasible criterion has not
    /// fallen by more than 1e-4 (relative) in this many evaluations (0: off;
    /// only `max_evals` and the tolerances end it).
    #[serde(skip_serializing_if = "is_zero")]
    pub patience: u32,
    /// A restart perturbs the coefficients of this many joints only
    /// ([`crate::trajectory::TrajectoryShape::joint_vars`]), drawn by the
    /// restart's seed (0: every variable). Variables outside every joint's
    /// range (a free centre's) do not move.
    #[serde(skip_serializing_if = "is_zero_usize")]
    pub perturb_joints: usize,
    /// Adaptive perturbation size (1: off, always `perturb`): every refined
    /// point a round of restarts perturbs carries its own size, `perturb` at
    /// first; after a round from it, the size is multiplied by this factor if
    /// the round found a better point than it (and the better point inherits
    /// the grown size) and divided by it otherwise, within [`perturb`/10,
    /// min(1, 4·`perturb`)].
    #[serde(skip_serializing_if = "is_one_f64")]
    pub perturb_adapt: f64,
    /// Repair the best near-feasible infeasible iterate of each refinement into the joint limits and keep it if better ([`super::refine::repair_near`]).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub repair: bool,
}

fn is_zero_usize(v: &usize) -> bool {
    *v == 0
}

fn is_one_f64(v: &f64) -> bool {
    *v == 1.0
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

fn is_one(v: &usize) -> bool {
    *v == 1
}

impl Default for RefineSpec {
    fn default() -> Self {
        RefineSpec {
            algorithm: RefineAlgorithm::Slsqp,
            starts: 2,
            max_evals: 300,
            xtol_rel: 1e-7,
            ftol_rel: 1e-9,
            smooth: 0.0,
            bundle: 0,
            bundle_weight: 0.1,
            parallel: 1,
            restarts: 0,
            perturb: 0.05,
            stall: 0,
            polish: 0,
            elites: 1,
            patience: 0,
            perturb_joints: 0,
            perturb_adapt: 1.0,
            repair: false,
        }
    }
}

impl ExciteDesign {
    /// Reads and validates a design file; the robot path is resolved relative
    /// to the file and the name defaults to the file stem.
    pub fn load(path: &Path) -> Result<ExciteDesign> {
        let mut d: ExciteDesign = crate::io::read_toml(path)?;
        if d.name.is_empty() {
            d.name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "excite".into());
        }
        d.robot = crate::io::design_path(path, "robot", &d.robot)?;
        {
            use crate::robot::collision::ShapeSpec;
            let shapes = (d.collision.obstacle.iter_mut().enumerate())
                .map(|(k, o)| (format!("collision.obstacle[{k}].shape.file"), &mut o.shape))
                .chain((d.collision.attached.iter_mut().enumerate()).map(|(k, a)| (format!("collision.attached[{k}].shape.file"), &mut a.shape)));
            for (field, sh) in shapes {
                if let ShapeSpec::Mesh { file, .. } = sh {
                    *file = crate::io::design_path(path, &field, file)?;
                }
            }
        }
        d.validate(&path.display().to_string())?;
        Ok(d)
    }

    /// Checks every value; `ctx` names the file in messages.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        let bad = |field: &str, msg: String| Err(Error::invalid(ctx, field, msg));
        if matches!(self.objective.columns, Columns::Payload | Columns::Gains) {
            if self.payload.is_none() {
                return bad(
                    "objective.columns",
                    "\"payload\" and \"gains\" excite a payload's (or a known mass's) parameters: add a [payload] section (frame, mass, com, inertia)".into(),
                );
            }
            if self.objective.base_columns.is_some() {
                return bad(
                    "objective.base_columns",
                    "the payload's columns are its ten parameters; base_columns applies to the robot's own parameters".into(),
                );
            }
        }
        if self.name.is_empty() || self.name.contains(['/', '\\']) {
            return bad("name", format!("expected a plain folder name, got `{}`", self.name));
        }
        if let Some(t) = self.time_limit {
            if !(t.is_finite() && t > 0.0) {
                return bad("time_limit", format!("expected a positive number of seconds, got {t}"));
            }
        }
        if self.max_evaluations == Some(0) {
            return bad("max_evaluations", "expected a positive number of criterion evaluations, got 0".into());
        }
        let tr = &self.trajectory;
        if tr.harmonics == 0 || tr.harmonics > 50 || (tr.at_rest && tr.harmonics < 2) {
            return bad(
                "trajectory.harmonics",
                format!("expected 1..=50 harmonics (≥ 2 with at_rest), got {}", tr.harmonics),
            );
        }
        if !(tr.frequency.is_finite() && tr.frequency > 0.0 && tr.frequency <= 100.0) {
            return bad(
                "trajectory.frequency",
                format!("expected a base frequency in (0, 100] Hz, got {}", tr.frequency),
            );
        }
        if !(tr.controller_rate.is_finite() && tr.controller_rate >= 1.0 && tr.controller_rate <= 1e5) {
            return bad("trajectory.controller_rate", format!("expected 1..=100000 Hz, got {}", tr.controller_rate));
        }
        if let Some(q0) = &tr.q0 {
            if let Some(j) = q0.iter().position(|v| !v.is_finite()) {
                return bad(&format!("trajectory.q0[{j}]"), "expected a finite number".into());
            }
        }
        tr.validate_shape(ctx)?;
        if tr.ends_elsewhere() && self.execution.periods != 1 {
            return bad(
                "execution.periods",
                format!(
                    "trajectory.end (free, or a pose other than the start) ends the motion elsewhere than it starts, so it cannot be repeated back to back: set execution.periods = 1 (got {}), or end = \"start\"",
                    self.execution.periods
                ),
            );
        }
        let o = &self.objective;
        // two samples per period of the highest harmonic, or per B-spline segment
        let nyq = match tr.shape {
            ShapeKind::Fourier => 2.0 * tr.harmonics as f64 * tr.frequency,
            ShapeKind::Bspline => 2.0 * tr.bspline_segments() as f64 / tr.motion_duration(),
        };
        if !(o.sample_rate.is_finite() && o.sample_rate > 0.0) {
            return bad("objective.sample_rate", format!("expected a positive rate in Hz, got {}", o.sample_rate));
        }
        if o.sample_rate * tr.motion_duration() > 1e6 {
            return bad("objective.sample_rate", "more than 10⁶ samples per period".into());
        }
        if o.sample_rate < nyq {
            let what = match tr.shape {
                ShapeKind::Fourier => "the highest harmonic",
                ShapeKind::Bspline => "segments per second",
            };
            return bad("objective.sample_rate", format!("{} Hz is below twice {what} ({nyq} Hz)", o.sample_rate));
        }
        if let Some(nz) = &o.noise {
            if let Some(j) = nz.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
                return bad(&format!("objective.noise[{j}]"), "expected a positive noise level".into());
            }
        }
        let l = &self.limits;
        if !(l.position > 0.0 && l.position <= 1.0) {
            return bad("limits.position", format!("expected a fraction in (0, 1], got {}", l.position));
        }
        for (f, v) in [
            ("limits.velocity", l.velocity),
            ("limits.acceleration", l.acceleration),
            ("limits.torque", l.torque),
        ] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return bad(f, format!("expected a fraction in [0, 1] (0: not imposed), got {v}"));
            }
        }
        for (f, v) in [("limits.grid_rate", l.grid_rate), ("limits.check_rate", l.check_rate)] {
            if !(v.is_finite() && v > 0.0 && v <= 1e5) {
                return bad(f, format!("expected a rate in (0, 100000] Hz, got {v}"));
            }
        }
        if let Some(r) = &l.position_range {
            for (j, [lo, hi]) in r.iter().enumerate() {
                if lo.is_nan() || hi.is_nan() || lo >= hi {
                    return bad(&format!("limits.position_range[{j}]"), format!("expected lower < upper, got [{lo}, {hi}]"));
                }
            }
        }
        for (i, w) in self.workspace.iter().enumerate() {
            w.shape.validate(ctx, &format!("workspace[{i}].shape"))?;
        }
        self.ga.validate(ctx)?;
        self.execution.validate(ctx)?;
        let r = &self.refine;
        if r.algorithm != RefineAlgorithm::None && (r.starts == 0 || r.max_evals == 0) {
            return bad(
                "refine.starts",
                "refinement needs at least one start and one evaluation (or algorithm = \"none\")".into(),
            );
        }
        if !(r.smooth == 0.0 || (r.smooth >= 1.0 && r.smooth <= 1000.0)) {
            return bad("refine.smooth", format!("expected 0 (off) or an exponent in [1, 1000], got {}", r.smooth));
        }
        if r.bundle > 24 {
            return bad("refine.bundle", format!("expected 0 (off) or 1..=24 eigenvalues at each end, got {}", r.bundle));
        }
        if !(r.bundle_weight.is_finite() && r.bundle_weight > 0.0 && r.bundle_weight <= 100.0) {
            return bad("refine.bundle_weight", format!("expected a weight in (0, 100], got {}", r.bundle_weight));
        }
        if r.bundle > 0 && o.criterion == Criterion::LogDet {
            return bad(
                "refine.bundle",
                "the epigraph form applies to criterion = \"cond\" or \"inv_sigma_min\" (log_det is smooth already); set bundle = 0".into(),
            );
        }
        if r.polish > 0 && r.algorithm != RefineAlgorithm::Slsqp {
            return bad(
                "refine.polish",
                format!(
                    "an MMA stage after each SLSQP stage: it applies to algorithm = \"slsqp\" only; set polish = 0 (got {})",
                    r.polish
                ),
            );
        }
        if r.polish > 1_000_000 {
            return bad("refine.polish", format!("expected 0 (off) or at most 1000000 evaluations, got {}", r.polish));
        }
        if !(r.perturb > 0.0 && r.perturb <= 1.0) {
            return bad("refine.perturb", format!("expected a fraction in (0, 1], got {}", r.perturb));
        }
        if r.stall > 1_000_000 {
            return bad(
                "refine.stall",
                format!("expected 0 (never) or a number of rounds up to 1000000, got {}", r.stall),
            );
        }
        if r.elites == 0 || r.elites > 1000 {
            return bad(
                "refine.elites",
                format!(
                    "expected 1 (the best point) to 1000 distinct refined points perturbed in turn, got {}",
                    r.elites
                ),
            );
        }
        if r.patience > 1_000_000 {
            return bad(
                "refine.patience",
                format!("expected 0 (off) or at most 1000000 evaluations, got {}", r.patience),
            );
        }
        if r.perturb_joints > 1000 {
            return bad(
                "refine.perturb_joints",
                format!(
                    "expected 0 (every variable) or a number of joints (at most the robot's), got {}",
                    r.perturb_joints
                ),
            );
        }
        if !(r.perturb_adapt >= 1.0 && r.perturb_adapt <= 10.0) {
            return bad(
                "refine.perturb_adapt",
                format!("expected a factor in [1, 10] (1: a fixed size), got {}", r.perturb_adapt),
            );
        }
        if r.parallel == 0 || r.parallel > 64 {
            return bad("refine.parallel", format!("expected 1..=64 starts at a time, got {}", r.parallel));
        }
        if !(r.xtol_rel >= 0.0 && r.ftol_rel >= 0.0) {
            return bad("refine.xtol_rel", "tolerances must be ≥ 0".into());
        }
        Ok(())
    }

    /// Per-joint checks that need the robot (q0 length, noise length, ranges).
    pub fn validate_for(&self, robot: &crate::robot::Robot, ctx: &str) -> Result<()> {
        let n = robot.dof();
        let check = |field: &str, len: usize| {
            if len != n {
                Err(Error::invalid(
                    ctx,
                    field,
                    format!("expected {n} values (one per joint of `{}`), got {len}", robot.name),
                ))
            } else {
                Ok(())
            }
        };
        if let Some(q0) = &self.trajectory.q0 {
            check("trajectory.q0", q0.len())?;
        }
        if let Some(nz) = &self.objective.noise {
            check("objective.noise", nz.len())?;
        }
        if let Some(r) = &self.limits.position_range {
            check("limits.position_range", r.len())?;
        }
        if let Some(h) = &self.execution.home {
            check("execution.home", h.len())?;
        }
        if let Some(q) = self.trajectory.start.given() {
            check("trajectory.start", q.len())?;
        }
        if let Some(q) = self.trajectory.end.given() {
            check("trajectory.end", q.len())?;
        }
        Ok(())
    }
}
